#include "symbolic/expr_print.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <sstream>
#include <string_view>

namespace obsynth {

using GiNaC::ex;
using GiNaC::ex_to;
using GiNaC::is_a;
using GiNaC::numeric;

namespace {

enum class Style { plain, latex };

std::string ginac_text(const ex& e) {
  std::ostringstream os;
  os << e;
  return os.str();
}
std::string int_text(const numeric& v) {
  // Machine-size integers without a stream (most exponents and coefficients); the same digits.
  static const numeric limit = numeric(1L << 62);
  if (v.is_integer() && GiNaC::abs(v) < limit) return std::to_string(v.to_long());
  return ginac_text(v);
}

// Binding strength of the printed form, to decide parentheses.
enum Prec { p_add = 1, p_mul = 2, p_unary = 3, p_pow = 4, p_atom = 5 };

struct Printed {
  std::string text;
  int prec;
  bool negative = false;  // text starts with '-'
};

class Printer {
 public:
  explicit Printer(Style s) : style_(s) {}

  Printed print(const ex& e) {
    if (is_a<numeric>(e)) return number(ex_to<numeric>(e));
    if (is_a<GiNaC::symbol>(e)) return {symbol_name(ex_to<GiNaC::symbol>(e).get_name()), p_atom};
    if (is_a<GiNaC::add>(e)) return sum(e);
    if (is_a<GiNaC::mul>(e)) return product(e);
    if (is_a<GiNaC::power>(e)) return power(e.op(0), e.op(1));
    if (is_a<GiNaC::function>(e)) return function(e);
    if (is_a<GiNaC::constant>(e)) {
      std::string s = ginac_text(e);
      if (style_ == Style::latex && s == "Pi") s = "\\pi";
      return {s, p_atom};
    }
    // Anything else (should not occur in models): GiNaC's own text.
    return {ginac_text(e), p_add};
  }

 private:
  Style style_;

  std::string symbol_name(const std::string& n) const {
    if (style_ == Style::plain) return n;
    // x12 -> x_{12}; names with underscores -> \mathrm{...}
    std::size_t k = n.size();
    while (k > 0 && std::isdigit(static_cast<unsigned char>(n[k - 1]))) --k;
    std::string base = n.substr(0, k), sub = n.substr(k);
    std::string out;
    for (char c : base) {
      if (c == '_')
        out += "\\_";
      else
        out += c;
    }
    if (base.size() > 1) out = "\\mathit{" + out + "}";
    if (!sub.empty()) out += "_{" + sub + "}";
    return out;
  }

  Printed number(const numeric& v) {
    if (v.is_integer()) {
      std::string s = int_text(v);
      return {s, v.is_negative() ? p_unary : p_atom, v.is_negative()};
    }
    if (v.is_rational()) {
      const numeric a = GiNaC::abs(v);
      std::string s =
          style_ == Style::latex
              ? fmt::format("\\frac{{{}}}{{{}}}", int_text(a.numer()), int_text(a.denom()))
              : fmt::format("{}/{}", int_text(a.numer()), int_text(a.denom()));
      if (v.is_negative()) return {"-" + s, p_unary, true};
      return {s, style_ == Style::latex ? p_atom : p_mul};
    }
    if (v.is_real()) {
      const double d = v.to_double();
      std::string s = fmt::format("{:.17g}", std::fabs(d));
      if (s.find_first_of(".e") == std::string::npos) s += ".0";
      if (d < 0) return {"-" + s, p_unary, true};
      return {s, p_atom};
    }
    // Complex numbers never come out of real models; print GiNaC's form in parentheses.
    return {"(" + ginac_text(v) + ")", p_atom};
  }

  static std::string wrap(const Printed& p, int min_prec, Style st) {
    if (p.prec >= min_prec) return p.text;
    return st == Style::latex ? "\\left(" + p.text + "\\right)" : "(" + p.text + ")";
  }

  // The terms of a sum, printed and in canonical order: by the text without sign so that x
  // and -x sort together, constants last.
  std::vector<Printed> sum_terms(const ex& e) {
    std::vector<Printed> terms;
    terms.reserve(e.nops());
    for (std::size_t i = 0; i < e.nops(); ++i) terms.push_back(print(e.op(i)));
    sort_terms(terms);
    return terms;
  }

  static void sort_terms(std::vector<Printed>& terms) {
    auto key = [](const Printed& p) {
      std::string_view t = p.text;
      if (p.negative) t.remove_prefix(1);
      const bool constant =
          !t.empty() && (std::isdigit(static_cast<unsigned char>(t[0])) || t[0] == '\\');
      return std::make_tuple(constant, t, p.negative);
    };
    std::sort(terms.begin(), terms.end(),
              [&](const Printed& a, const Printed& b) { return key(a) < key(b); });
  }

  // -(t1 + t2 + ...) from the printed terms, without building -e: GiNaC would re-evaluate
  // it (and printing it again would cost as much as the first time at every nesting level).
  static std::vector<Printed> negated(std::vector<Printed> terms) {
    for (Printed& t : terms) {
      if (t.negative) {
        t.text.erase(0, 1);
        t.negative = false;
      } else {
        t.text.insert(0, 1, '-');
        t.negative = true;
      }
    }
    sort_terms(terms);
    return terms;
  }

  static Printed join_terms(const std::vector<Printed>& terms) {
    std::string out;
    for (std::size_t i = 0; i < terms.size(); ++i) {
      const Printed& t = terms[i];
      if (i > 0 && !t.negative) out += '+';
      out += t.text;
    }
    return {out, p_add, !terms.empty() && terms[0].negative};
  }

  Printed sum(const ex& e) { return join_terms(sum_terms(e)); }

  // base^k for an already printed base and an integer k >= 1.
  Printed integer_power(const Printed& base, const numeric& k) const {
    if (k == 1) return base;
    if (style_ == Style::latex)
      return {fmt::format("{}^{{{}}}", wrap(base, p_atom, style_), int_text(k)), p_pow};
    return {fmt::format("{}^{}", wrap(base, p_atom, style_), int_text(k)), p_pow};
  }

  // The factors of a product with its exp factors (and integer powers of them) merged into
  // one exp of the expanded sum of arguments, so that exp(a)*exp(-a) never prints.
  static GiNaC::exvector merged_factors(const ex& e) {
    GiNaC::exvector out;
    ex arg = 0;
    int exps = 0;
    for (std::size_t i = 0; i < e.nops(); ++i) {
      const ex f = e.op(i);
      if (is_exp(f)) {
        arg += f.op(0);
        ++exps;
      } else if (is_exp_power(f)) {
        arg += f.op(1) * f.op(0).op(0);
        exps += 2;
      } else {
        out.push_back(f);
      }
    }
    if (exps < 2) {
      out.clear();
      for (std::size_t i = 0; i < e.nops(); ++i) out.push_back(e.op(i));
      return out;
    }
    arg = GiNaC::expand(arg);
    if (!arg.is_zero()) out.push_back(GiNaC::exp(arg));
    return out;
  }

  static bool is_exp(const ex& e) {
    return is_a<GiNaC::function>(e) && ex_to<GiNaC::function>(e).get_name() == "exp";
  }
  static bool is_exp_power(const ex& e) {
    return is_a<GiNaC::power>(e) && is_exp(e.op(0)) && is_a<numeric>(e.op(1)) &&
           ex_to<numeric>(e.op(1)).is_integer();
  }

  Printed product(const ex& e) {
    numeric coeff = 1;
    std::vector<std::string> num, den;
    const GiNaC::exvector factors = merged_factors(e);
    for (const ex& f0 : factors) {
      ex f = f0;
      if (is_a<numeric>(f) && ex_to<numeric>(f).is_rational()) {
        coeff *= ex_to<numeric>(f);
        continue;
      }
      // Sign normal form: a sum factor whose first printed term is negative is negated and
      // the sign moved to the coefficient, so -(a-b)/c and (b-a)/c print alike (GiNaC's
      // normal() picks either, depending on run-dependent term order).
      {
        ex base = f;
        numeric k = 1;
        if (is_a<GiNaC::power>(f) && is_a<numeric>(f.op(1)) &&
            ex_to<numeric>(f.op(1)).is_integer()) {
          base = f.op(0);
          k = ex_to<numeric>(f.op(1));
        }
        if (is_a<GiNaC::add>(base)) {
          std::vector<Printed> terms = sum_terms(base);
          if (!terms.empty() && terms[0].negative) {
            terms = negated(std::move(terms));
            if (k.is_odd()) coeff = -coeff;
          }
          const Printed b = join_terms(terms);
          if (k.is_negative())
            den.push_back(wrap(integer_power(b, -k), p_pow, style_));
          else
            num.push_back(wrap(integer_power(b, k), p_mul + 1, style_));
          continue;
        }
      }
      if (is_a<GiNaC::power>(f) && is_a<numeric>(f.op(1)) &&
          ex_to<numeric>(f.op(1)).is_negative()) {
        const ex inv = GiNaC::pow(f.op(0), -f.op(1));
        den.push_back(wrap(print(inv), p_pow, style_));
        continue;
      }
      num.push_back(wrap(print(f), p_mul + 1, style_));
    }
    std::sort(num.begin(), num.end());
    std::sort(den.begin(), den.end());
    const bool neg = coeff.is_negative();
    const numeric a = GiNaC::abs(coeff);
    const numeric cn = a.numer(), cd = a.denom();
    if (cn != 1 || num.empty()) num.insert(num.begin(), int_text(cn));
    if (cd != 1) den.insert(den.begin(), int_text(cd));
    const char* times = style_ == Style::latex ? " " : "*";
    std::string top = fmt::format("{}", fmt::join(num, times));
    std::string out;
    if (den.empty()) {
      out = top;
    } else if (style_ == Style::latex) {
      out = fmt::format("\\frac{{{}}}{{{}}}", top, fmt::join(den, " "));
    } else {
      std::string bottom = fmt::format("{}", fmt::join(den, "*"));
      if (den.size() > 1) bottom = "(" + bottom + ")";
      out = top + "/" + bottom;
    }
    if (neg) return {"-" + out, p_unary, true};
    return {out, den.empty() || style_ == Style::latex ? p_mul : p_mul};
  }

  Printed power(const ex& base, const ex& expo) {
    if (is_exp(base) && is_a<numeric>(expo) && ex_to<numeric>(expo).is_integer())
      return call("exp", GiNaC::expand(expo * base.op(0)));  // exp(a)^k as exp(k*a)
    if (is_a<numeric>(expo)) {
      const numeric q = ex_to<numeric>(expo);
      if (q == numeric(1, 2)) return call("sqrt", base);
      if (q.is_negative()) {
        const Printed d = print(GiNaC::pow(base, -q));
        if (style_ == Style::latex) return {fmt::format("\\frac{{1}}{{{}}}", d.text), p_atom};
        return {"1/" + wrap(d, p_pow, style_), p_mul};
      }
    }
    if (is_a<GiNaC::add>(base) && is_a<numeric>(expo) && ex_to<numeric>(expo).is_pos_integer()) {
      // The sign normal form of sum factors (product()): (-a+b)^k prints as (a-b)^k, with the
      // sign in front for odd k.
      std::vector<Printed> terms = sum_terms(base);
      const bool flip = !terms.empty() && terms[0].negative;
      if (flip) terms = negated(std::move(terms));
      const Printed p = integer_power(join_terms(terms), ex_to<numeric>(expo));
      if (flip && ex_to<numeric>(expo).is_odd()) return {"-" + p.text, p_unary, true};
      return p;
    }
    const Printed b = print(base);
    const Printed x = print(expo);
    if (style_ == Style::latex)
      return {fmt::format("{}^{{{}}}", wrap(b, p_atom, style_), x.text), p_pow};
    return {fmt::format("{}^{}", wrap(b, p_atom, style_), wrap(x, p_atom, style_)), p_pow};
  }

  Printed call(const std::string& name, const ex& arg) {
    const Printed a = print(arg);
    if (style_ == Style::latex) {
      if (name == "sqrt") return {fmt::format("\\sqrt{{{}}}", a.text), p_atom};
      const bool known = name == "sin" || name == "cos" || name == "tan" || name == "exp" ||
                         name == "log" || name == "tanh";
      const std::string fn =
          known ? "\\" + name : (name == "atan" ? "\\arctan" : "\\operatorname{" + name + "}");
      return {fmt::format("{}\\left({}\\right)", fn, a.text), p_atom};
    }
    return {fmt::format("{}({})", name, a.text), p_atom};
  }

  Printed function(const ex& e) {
    const std::string name = ex_to<GiNaC::function>(e).get_name();
    if (e.nops() == 1) return call(name, e.op(0));
    std::vector<std::string> args;
    for (std::size_t i = 0; i < e.nops(); ++i) args.push_back(print(e.op(i)).text);
    return {fmt::format("{}({})", name, fmt::join(args, ",")), p_atom};
  }
};

}  // namespace

namespace {
PrintCache* g_print_cache = nullptr;

template <class Map>
std::string print_cached(Map* texts, const ex& e, Style style) {
  if (!texts) return Printer(style).print(e).text;
  const GiNaC::basic* key = &ex_to<GiNaC::basic>(e);
  auto it = texts->find(key);
  if (it == texts->end())
    it = texts->emplace(key, std::pair(e, Printer(style).print(e).text)).first;
  return it->second.second;
}
}  // namespace

PrintCache::Use::Use(PrintCache& cache) : previous_(g_print_cache) {
  g_print_cache = &cache;
}
PrintCache::Use::~Use() {
  g_print_cache = previous_;
}

std::string to_string(const ex& e) {
  return print_cached(g_print_cache ? &g_print_cache->plain_ : nullptr, e, Style::plain);
}
std::string to_latex(const ex& e) {
  return print_cached(g_print_cache ? &g_print_cache->latex_ : nullptr, e, Style::latex);
}

std::vector<std::string> to_strings(const std::vector<ex>& v) {
  std::vector<std::string> out;
  out.reserve(v.size());
  for (const auto& e : v) out.push_back(to_string(e));
  return out;
}

}  // namespace obsynth
