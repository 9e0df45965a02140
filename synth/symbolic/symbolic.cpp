#include "symbolic/symbolic.hpp"

#include <algorithm>
#include <map>
#include <set>

#include "symbolic/expr_print.hpp"
#include "symbolic/poly.hpp"

namespace obsynth {

namespace {
void collect(const GiNaC::ex& e, std::vector<GiNaC::symbol>& out, std::set<std::string>& seen) {
  if (GiNaC::is_a<GiNaC::symbol>(e)) {
    const auto& s = GiNaC::ex_to<GiNaC::symbol>(e);
    if (seen.insert(s.get_name()).second) out.push_back(s);
    return;
  }
  for (std::size_t i = 0; i < e.nops(); ++i) collect(e.op(i), out, seen);
}
}  // namespace

std::vector<GiNaC::symbol> symbols_in(const GiNaC::ex& e) {
  std::vector<GiNaC::symbol> out;
  std::set<std::string> seen;
  collect(e, out, seen);
  std::sort(out.begin(), out.end(), [](const GiNaC::symbol& a, const GiNaC::symbol& b) {
    return a.get_name() < b.get_name();
  });
  return out;
}

bool depends_on(const GiNaC::ex& e, const std::vector<GiNaC::symbol>& syms) {
  for (const auto& s : syms)
    if (e.has(s)) return true;
  return false;
}

std::size_t expression_size(const GiNaC::ex& e) {
  std::size_t n = 1;
  for (std::size_t i = 0; i < e.nops(); ++i) n += expression_size(e.op(i));
  return n;
}

bool has_transcendental(const GiNaC::ex& e) {
  if (GiNaC::is_a<GiNaC::function>(e)) return true;
  if (GiNaC::is_a<GiNaC::power>(e)) {
    const GiNaC::ex ex = e.op(1);
    if (!(GiNaC::is_a<GiNaC::numeric>(ex) && GiNaC::ex_to<GiNaC::numeric>(ex).is_integer()))
      return true;
  }
  for (std::size_t i = 0; i < e.nops(); ++i)
    if (has_transcendental(e.op(i))) return true;
  return false;
}

namespace {
// A negative power (or tan = sin/cos) whose base `matters`, anywhere in e.
template <class Matters>
bool has_denominator(const GiNaC::ex& e, const Matters& matters) {
  if (GiNaC::is_a<GiNaC::power>(e) && GiNaC::is_a<GiNaC::numeric>(e.op(1)) &&
      GiNaC::ex_to<GiNaC::numeric>(e.op(1)).is_negative() && matters(e.op(0)))
    return true;
  if (GiNaC::is_a<GiNaC::function>(e) && GiNaC::ex_to<GiNaC::function>(e).get_name() == "tan" &&
      matters(e))
    return true;
  for (std::size_t i = 0; i < e.nops(); ++i)
    if (has_denominator(e.op(i), matters)) return true;
  return false;
}
}  // namespace

bool has_denominator_in(const GiNaC::ex& e, const std::vector<GiNaC::symbol>& syms) {
  return has_denominator(e, [&](const GiNaC::ex& base) { return depends_on(base, syms); });
}

bool has_symbolic_denominator(const GiNaC::ex& e) {
  return has_denominator(e,
                         [](const GiNaC::ex& base) { return !GiNaC::is_a<GiNaC::numeric>(base); });
}

std::vector<GiNaC::ex> gradient(const GiNaC::ex& e, const std::vector<GiNaC::symbol>& vars) {
  std::vector<GiNaC::ex> out;
  out.reserve(vars.size());
  for (const auto& v : vars) out.push_back(e.diff(v));
  return out;
}

namespace {

bool is_exp(const GiNaC::ex& e) {
  return GiNaC::is_a<GiNaC::function>(e) && GiNaC::ex_to<GiNaC::function>(e).get_name() == "exp";
}

bool is_trig(const GiNaC::ex& e) {
  if (!GiNaC::is_a<GiNaC::function>(e) || e.nops() != 1) return false;
  const std::string& name = GiNaC::ex_to<GiNaC::function>(e).get_name();
  return name == "sin" || name == "cos";
}

// exp(a)^k (k an integer, exp(a) itself for k = 1): adds k*a to `arg`.
bool take_exponential(const GiNaC::ex& f, GiNaC::ex& arg) {
  if (is_exp(f)) {
    arg += f.op(0);
    return true;
  }
  if (GiNaC::is_a<GiNaC::power>(f) && is_exp(f.op(0)) && GiNaC::is_a<GiNaC::numeric>(f.op(1)) &&
      GiNaC::ex_to<GiNaC::numeric>(f.op(1)).is_integer()) {
    arg += f.op(1) * f.op(0).op(0);
    return true;
  }
  return false;
}

using UnitMap = std::map<GiNaC::ex, GiNaC::numeric, GiNaC::ex_is_less>;

void note_exp_units(const GiNaC::ex& e, UnitMap& units) {
  if (is_exp(e))
    if (const auto terms = argument_terms(e.op(0)))
      for (const auto& [c, t] : *terms) {
        auto [it, fresh] = units.emplace(t, GiNaC::abs(c));
        if (!fresh) it->second = rational_gcd(it->second, c);
      }
  for (std::size_t i = 0; i < e.nops(); ++i) note_exp_units(e.op(i), units);
}

// exp(sum c_i t_i) as prod exp(u_i t_i)^(c_i/u_i): normal() then cancels exp factors.
GiNaC::ex to_exp_bases(const GiNaC::ex& e, const UnitMap& units) {
  if (is_exp(e)) {
    const auto terms = argument_terms(e.op(0));
    if (!terms) return e;
    GiNaC::ex out = 1;
    for (const auto& [c, t] : *terms) {
      const auto it = units.find(t);
      out *= GiNaC::pow(GiNaC::exp(it->second * t), c / it->second);
    }
    return out;
  }
  if (e.nops() == 0) return e;
  struct Recurse : GiNaC::map_function {
    const UnitMap& units;
    explicit Recurse(const UnitMap& u) : units(u) {}
    GiNaC::ex operator()(const GiNaC::ex& op) override { return to_exp_bases(op, units); }
  } recurse(units);
  return e.map(recurse);
}

class CombineExponentials : public GiNaC::map_function {
 public:
  GiNaC::ex operator()(const GiNaC::ex& e) override {
    if (e.nops() == 0) return e;
    const GiNaC::ex mapped = e.map(*this);
    GiNaC::ex arg = 0;
    if (take_exponential(mapped, arg)) return GiNaC::exp(GiNaC::expand(arg));
    if (!GiNaC::is_a<GiNaC::mul>(mapped)) return mapped;
    GiNaC::ex rest = 1;
    int exps = 0;
    for (std::size_t i = 0; i < mapped.nops(); ++i) {
      if (take_exponential(mapped.op(i), arg))
        ++exps;
      else
        rest *= mapped.op(i);
    }
    if (exps < 2 && !(exps == 1 && arg.is_zero())) return mapped;
    return rest * GiNaC::exp(GiNaC::expand(arg));
  }
};

// normal() with exp factors cancelled: exp atoms as powers of common bases, then the exp
// factors of the denominator moved into the (expanded) numerator.
GiNaC::ex normal_with_exponentials(const GiNaC::ex& e) {
  UnitMap units;
  note_exp_units(e, units);
  const GiNaC::ex nd = GiNaC::numer_denom(GiNaC::normal(to_exp_bases(e, units)));
  const GiNaC::ex den = nd.op(1);
  GiNaC::ex den_arg = 0, den_rest = 1;
  const std::size_t count = GiNaC::is_a<GiNaC::mul>(den) ? den.nops() : 1;
  for (std::size_t i = 0; i < count; ++i) {
    const GiNaC::ex f = GiNaC::is_a<GiNaC::mul>(den) ? den.op(i) : den;
    if (!take_exponential(f, den_arg)) den_rest *= f;
  }
  const GiNaC::ex num =
      combine_exponentials(GiNaC::expand(nd.op(0) * GiNaC::exp(-GiNaC::expand(den_arg))));
  return num / den_rest;
}

// Whether e has exp atoms, and a denominator other than an exp power (which the ring holds
// as a Laurent monomial).
struct Shape {
  bool exp = false, denominator = false, trig = false;
};

void shape_of(const GiNaC::ex& e, Shape& shape) {
  if (is_exp(e)) shape.exp = true;
  if (is_trig(e)) shape.trig = true;
  if (GiNaC::is_a<GiNaC::power>(e) && !is_exp(e.op(0)) && GiNaC::is_a<GiNaC::numeric>(e.op(1)) &&
      GiNaC::ex_to<GiNaC::numeric>(e.op(1)).is_negative() && !GiNaC::is_a<GiNaC::numeric>(e.op(0)))
    shape.denominator = true;
  if (GiNaC::is_a<GiNaC::function>(e) && GiNaC::ex_to<GiNaC::function>(e).get_name() == "tan")
    shape.denominator = true;
  for (std::size_t i = 0; i < e.nops() && !(shape.exp && shape.denominator && shape.trig); ++i)
    shape_of(e.op(i), shape);
}

// sin/cos of several integer multiples of one angle as polynomials in that angle's sin and
// cos (de Moivre), as the ring does, for the expressions that stay in GiNaC.
struct Angle {
  GiNaC::numeric unit, first;
  bool several = false;
};
using AngleMap = std::map<GiNaC::ex, Angle, GiNaC::ex_is_less>;

void note_angles(const GiNaC::ex& e, AngleMap& angles) {
  if (is_trig(e))
    if (const auto d = argument_direction(e.op(0))) {
      auto [it, fresh] = angles.emplace(d->key, Angle{GiNaC::abs(d->multiple), d->multiple});
      if (!fresh) {
        it->second.unit = rational_gcd(it->second.unit, d->multiple);
        it->second.several |= it->second.first != d->multiple;
      }
    }
  for (std::size_t i = 0; i < e.nops(); ++i) note_angles(e.op(i), angles);
}

GiNaC::ex to_angle_bases(const GiNaC::ex& e, const AngleMap& angles) {
  if (is_trig(e)) {
    const auto d = argument_direction(e.op(0));
    const auto it = d ? angles.find(d->key) : angles.end();
    if (it == angles.end() || !it->second.several) return e;
    const GiNaC::ex angle = it->second.unit * d->key;
    const GiNaC::ex s = GiNaC::sin(angle), c = GiNaC::cos(angle);
    const GiNaC::numeric k = d->multiple / it->second.unit;
    GiNaC::ex cos_k = 0, sin_k = 0;  // (c + i s)^|k| = sum_j C(|k|, j) c^(|k|-j) (i s)^j
    const long m = GiNaC::abs(k).to_long();
    GiNaC::numeric binom = 1;
    for (long j = 0; j <= m; ++j) {
      const GiNaC::ex term = binom * GiNaC::pow(c, m - j) * GiNaC::pow(s, j);
      (j % 2 == 0 ? cos_k : sin_k) += (j / 2) % 2 == 0 ? term : -term;
      binom = binom * (m - j) / (j + 1);
    }
    if (GiNaC::ex_to<GiNaC::function>(e).get_name() == "cos") return cos_k;
    return k.is_negative() ? -sin_k : sin_k;
  }
  if (e.nops() == 0) return e;
  struct Recurse : GiNaC::map_function {
    const AngleMap& angles;
    explicit Recurse(const AngleMap& a) : angles(a) {}
    GiNaC::ex operator()(const GiNaC::ex& op) override { return to_angle_bases(op, angles); }
  } recurse(angles);
  return e.map(recurse);
}

}  // namespace

std::optional<std::vector<ArgumentTerm>> argument_terms(const GiNaC::ex& arg) {
  std::vector<ArgumentTerm> out;
  const GiNaC::ex e = GiNaC::expand(arg);
  auto take = [&](const GiNaC::ex& t) {
    if (GiNaC::is_a<GiNaC::numeric>(t)) {
      out.push_back({GiNaC::ex_to<GiNaC::numeric>(t), 1});
    } else if (GiNaC::is_a<GiNaC::mul>(t) && GiNaC::is_a<GiNaC::numeric>(t.op(t.nops() - 1))) {
      const GiNaC::ex c = t.op(t.nops() - 1);  // GiNaC keeps the numeric coefficient last
      out.push_back({GiNaC::ex_to<GiNaC::numeric>(c), t / c});
    } else {
      out.push_back({1, t});
    }
    return out.back().coeff.is_rational();
  };
  if (GiNaC::is_a<GiNaC::add>(e)) {
    for (std::size_t i = 0; i < e.nops(); ++i)
      if (!take(e.op(i))) return std::nullopt;
  } else if (!e.is_zero() && !take(e)) {
    return std::nullopt;
  }
  return out;
}

GiNaC::numeric rational_gcd(const GiNaC::numeric& a, const GiNaC::numeric& b) {
  return GiNaC::gcd(a.numer(), b.numer()) / GiNaC::lcm(a.denom(), b.denom());
}

std::optional<ArgumentDirection> argument_direction(const GiNaC::ex& arg) {
  const auto terms = argument_terms(arg);
  if (!terms || terms->empty()) return std::nullopt;
  GiNaC::numeric content = 0;
  const ArgumentTerm* first = nullptr;
  std::string first_text;
  for (const ArgumentTerm& t : *terms) {
    content = content.is_zero() ? GiNaC::abs(t.coeff) : rational_gcd(content, t.coeff);
    const std::string text = to_string(t.monomial);
    if (!first || text < first_text) {
      first = &t;
      first_text = text;
    }
  }
  const GiNaC::numeric multiple = first->coeff.is_negative() ? -content : content;
  GiNaC::ex key = 0;
  for (const ArgumentTerm& t : *terms) key += (t.coeff / multiple) * t.monomial;
  return ArgumentDirection{multiple, key};
}

GiNaC::ex combine_exponentials(const GiNaC::ex& e) {
  CombineExponentials combine;
  return combine(e);
}

// normal() cancels common factors of fractions but costs gcds; an expression without a
// symbolic denominator is a polynomial in its symbols and function atoms, for which the
// expanded form (with canonical atoms) is zero exactly when normal() would give zero and
// much cheaper to reach on large Lie derivatives and brackets. The ring's form is canonical
// for exp and multiple angles; outside it (atan, log, sqrt, exponents out of range) GiNaC's.
GiNaC::ex simplify(const GiNaC::ex& e) {
  Shape shape;
  shape_of(e, shape);
  // A polynomial (Laurent in exp): the ring's canonical form, which also multiplies out
  // nested products faster than expand() (dense chain family: 1.2 s against 2.4 s).
  if (!shape.denominator)
    if (const auto r = PolyRing::canonical_form(e)) return *r;
  GiNaC::ex r = e;
  if (shape.trig) {
    AngleMap angles;
    note_angles(e, angles);
    if (std::any_of(angles.begin(), angles.end(), [](const auto& a) { return a.second.several; }))
      r = to_angle_bases(e, angles);
  }
  if (!shape.exp) return shape.denominator ? GiNaC::normal(r) : GiNaC::expand(r);
  if (!shape.denominator) return combine_exponentials(GiNaC::expand(r));
  return normal_with_exponentials(r);
}

}  // namespace obsynth
