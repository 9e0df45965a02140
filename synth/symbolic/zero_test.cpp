#include "symbolic/zero_test.hpp"

#include <map>
#include <random>

#include "symbolic/symbolic.hpp"

namespace obsynth {

using GiNaC::ex;
using GiNaC::ex_to;
using GiNaC::is_a;
using GiNaC::numeric;

const char* verdict_name(ZeroVerdict v) {
  switch (v) {
    case ZeroVerdict::proved:
      return "proved";
    case ZeroVerdict::numeric:
      return "numeric";
    case ZeroVerdict::nonzero:
      return "nonzero";
  }
  return "nonzero";
}

DigitsGuard::DigitsGuard(long digits) : saved_(GiNaC::Digits) {
  GiNaC::Digits = digits;
}
DigitsGuard::~DigitsGuard() {
  GiNaC::Digits = saved_;
}

SampleBoxes SampleBoxes::from_model(const Model& m) {
  SampleBoxes b;
  for (const auto& s : m.all_symbols()) b.by_name[s.get_name()] = m.box(s);
  return b;
}

Interval SampleBoxes::box(const GiNaC::symbol& s) const {
  auto it = by_name.find(s.get_name());
  if (it != by_name.end()) return it->second;
  return {numeric(-2), numeric(2)};
}

// ---------------------------------------------------------------------------------------
// Sound rational rewrite.
namespace {

// A term of an argument: rational coefficient times a monomial key.
struct Term {
  numeric coeff;
  ex monomial;
};

std::vector<Term> split_linear(const ex& arg) {
  std::vector<Term> out;
  const ex e = GiNaC::expand(arg);
  auto add_term = [&](const ex& t) {
    if (is_a<numeric>(t)) {
      const numeric& c = ex_to<numeric>(t);
      if (c.is_rational()) {
        out.push_back({c, ex(1)});
        return;
      }
      out.push_back({numeric(1), t});
      return;
    }
    if (is_a<GiNaC::mul>(t)) {
      const ex c = t.op(t.nops() - 1);  // GiNaC keeps the numeric coefficient last
      if (is_a<numeric>(c) && ex_to<numeric>(c).is_rational()) {
        out.push_back({ex_to<numeric>(c), t / c});
        return;
      }
    }
    out.push_back({numeric(1), t});
  };
  if (is_a<GiNaC::add>(e)) {
    for (std::size_t i = 0; i < e.nops(); ++i) add_term(e.op(i));
  } else if (!e.is_zero()) {
    add_term(e);
  }
  return out;
}

struct Pair {  // cos and sin of an angle, as rational functions
  ex c, s;
};
Pair mul(const Pair& a, const Pair& b) {
  return {a.c * b.c - a.s * b.s, a.s * b.c + a.c * b.s};
}

constexpr long kMaxMultiple = 24;

class Rewriter {
 public:
  ex run(const ex& e) {
    prepass(e);
    return rewrite(e);
  }

 private:
  std::map<ex, numeric, GiNaC::ex_is_less> trig_base_, exp_base_;
  std::map<ex, GiNaC::symbol, GiNaC::ex_is_less> trig_sym_, exp_sym_, atom_sym_;
  int counter_ = 0;

  GiNaC::symbol fresh(const char* prefix) {
    return GiNaC::symbol(std::string(prefix) + std::to_string(counter_++));
  }

  static void note_base(std::map<ex, numeric, GiNaC::ex_is_less>& bases, const ex& arg) {
    for (const auto& t : split_linear(arg)) {
      auto it = bases.find(t.monomial);
      if (it == bases.end())
        bases.emplace(t.monomial, GiNaC::abs(t.coeff));
      else
        it->second = rational_gcd(it->second, t.coeff);
    }
  }

  void prepass(const ex& e) {
    if (is_a<GiNaC::function>(e)) {
      const std::string name = ex_to<GiNaC::function>(e).get_name();
      if (name == "sin" || name == "cos" || name == "tan") note_base(trig_base_, e.op(0));
      if (name == "exp") note_base(exp_base_, e.op(0));
      if (name == "tanh") note_base(exp_base_, 2 * e.op(0));
    }
    for (std::size_t i = 0; i < e.nops(); ++i) prepass(e.op(i));
  }

  ex atom(const ex& key) {
    auto it = atom_sym_.find(key);
    if (it != atom_sym_.end()) return it->second;
    GiNaC::symbol s = fresh("atom");
    atom_sym_.emplace(key, s);
    return s;
  }

  // e^{i*arg} as a (cos, sin) pair of rational functions, or nullopt-like failure.
  bool angle(const ex& arg, Pair& out) {
    Pair acc{1, 0};
    for (const auto& t : split_linear(arg)) {
      const numeric base = trig_base_.at(t.monomial);
      const numeric k = t.coeff / base;
      if (!k.is_integer() || GiNaC::abs(k) > kMaxMultiple) return false;
      auto it = trig_sym_.find(t.monomial);
      if (it == trig_sym_.end()) it = trig_sym_.emplace(t.monomial, fresh("tanhalf")).first;
      const ex tt = it->second;
      const Pair unit{(1 - tt * tt) / (1 + tt * tt), 2 * tt / (1 + tt * tt)};
      Pair p{1, 0};
      const long kk = k.to_long();
      for (long j = 0; j < std::labs(kk); ++j) p = mul(p, unit);
      if (kk < 0) p.s = -p.s;
      acc = mul(acc, p);
    }
    out = {GiNaC::normal(acc.c), GiNaC::normal(acc.s)};
    return true;
  }

  bool exponential(const ex& arg, ex& out) {
    ex acc = 1;
    for (const auto& t : split_linear(arg)) {
      const numeric base = exp_base_.at(t.monomial);
      const numeric k = t.coeff / base;
      if (!k.is_integer() || GiNaC::abs(k) > kMaxMultiple) return false;
      auto it = exp_sym_.find(t.monomial);
      if (it == exp_sym_.end()) it = exp_sym_.emplace(t.monomial, fresh("expbase")).first;
      acc *= GiNaC::pow(it->second, k);
    }
    out = acc;
    return true;
  }

  ex rewrite(const ex& e) {
    if (is_a<GiNaC::function>(e)) {
      const std::string name = ex_to<GiNaC::function>(e).get_name();
      const ex arg = e.nops() == 1 ? e.op(0) : ex();
      if (name == "sin" || name == "cos" || name == "tan") {
        // The argument itself is kept as the key: rewriting inside it would change keys.
        Pair p;
        if (angle(arg, p)) {
          if (name == "sin") return p.s;
          if (name == "cos") return p.c;
          return p.s / p.c;
        }
        return atom(e);
      }
      if (name == "exp" || name == "tanh") {
        ex v;
        if (exponential(name == "exp" ? arg : 2 * arg, v))
          return name == "exp" ? v : (v - 1) / (v + 1);
        return atom(e);
      }
      // log, atan, ...: opaque atom keyed by the function with rewritten arguments.
      GiNaC::exvector args;
      for (std::size_t i = 0; i < e.nops(); ++i) args.push_back(GiNaC::normal(rewrite(e.op(i))));
      ex key = e;
      for (std::size_t i = 0; i < e.nops(); ++i) key = key.subs(e.op(i) == args[i]);
      return atom(key);
    }
    if (is_a<GiNaC::power>(e)) {
      const ex b = rewrite(e.op(0));
      const ex x = e.op(1);
      if (is_a<numeric>(x)) {
        const numeric& q = ex_to<numeric>(x);
        if (q.is_integer()) return GiNaC::pow(b, q);
        if (q.is_rational()) {
          // b^(p/d) = (b^(1/d))^p with b^(1/d) an atom keyed by (normal(b), d).
          const ex root = atom(GiNaC::pow(GiNaC::normal(b), numeric(1) / q.denom()));
          return GiNaC::pow(root, q.numer());
        }
      }
      return atom(GiNaC::pow(GiNaC::normal(b), rewrite(x)));
    }
    if (is_a<GiNaC::add>(e) || is_a<GiNaC::mul>(e)) {
      ex acc = is_a<GiNaC::add>(e) ? ex(0) : ex(1);
      for (std::size_t i = 0; i < e.nops(); ++i) {
        if (is_a<GiNaC::add>(e))
          acc += rewrite(e.op(i));
        else
          acc *= rewrite(e.op(i));
      }
      return acc;
    }
    return e;
  }
};

std::uint64_t splitmix(std::uint64_t& s) {
  std::uint64_t z = (s += 0x9e3779b97f4a7c15ULL);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

}  // namespace

ex rational_rewrite(const ex& e) {
  return Rewriter().run(e);
}

bool proved_zero(const ex& e) {
  if (e.is_zero()) return true;
  try {
    if (!has_transcendental(e)) return GiNaC::normal(e).is_zero();
    if (GiNaC::normal(e).is_zero()) return true;
    return GiNaC::normal(rational_rewrite(e)).is_zero();
  } catch (const std::exception&) {
    return false;  // e.g. a division by zero exposed by the rewrite: not a proof
  }
}

bool evaluate_real(const ex& e, const GiNaC::exmap& point, int digits, numeric& value) {
  DigitsGuard guard(digits);
  try {
    // Substitute floating values (at this precision), not the exact rationals: exact
    // evaluation of a large rational expression builds numbers of millions of digits.
    GiNaC::exmap fpoint;
    for (const auto& [k, v] : point) fpoint[k] = GiNaC::evalf(v);
    const ex v = GiNaC::evalf(e.subs(fpoint));
    if (!is_a<numeric>(v)) return false;
    const numeric& nv = ex_to<numeric>(v);
    if (!nv.is_real()) {
      const numeric im = GiNaC::abs(nv.imag());
      if (im > numeric(10).power(numeric(-(digits / 2))) * (1 + GiNaC::abs(nv.real())))
        return false;
      value = nv.real();
      return true;
    }
    value = nv;
    return true;
  } catch (const std::exception&) {
    return false;
  }
}

namespace {

// Value and magnitude bound of e at a floating point (already evalf'd), or false.
bool eval_mag(const ex& e, const GiNaC::exmap& fpoint, numeric& value, numeric& mag) {
  if (is_a<numeric>(e)) {
    value = ex_to<numeric>(GiNaC::evalf(e));
    mag = GiNaC::abs(value);
    return value.is_real();
  }
  if (is_a<GiNaC::add>(e) || is_a<GiNaC::mul>(e)) {
    const bool sum = is_a<GiNaC::add>(e);
    value = sum ? 0 : 1;
    mag = sum ? 0 : 1;
    for (std::size_t i = 0; i < e.nops(); ++i) {
      numeric v, m;
      if (!eval_mag(e.op(i), fpoint, v, m)) return false;
      if (sum) {
        value += v;
        mag += m;
      } else {
        value *= v;
        mag *= m;
      }
    }
    return true;
  }
  if (is_a<GiNaC::power>(e) && is_a<numeric>(e.op(1)) && ex_to<numeric>(e.op(1)).is_integer()) {
    numeric v, m;
    if (!eval_mag(e.op(0), fpoint, v, m)) return false;
    const numeric k = ex_to<numeric>(e.op(1));
    if (v.is_zero() && k.is_negative()) return false;
    value = v.power(k);
    mag = k.is_negative() ? GiNaC::abs(value) : m.power(k);
    return true;
  }
  if (is_a<GiNaC::symbol>(e)) {
    const auto it = fpoint.find(e);
    if (it != fpoint.end() && is_a<numeric>(it->second)) {
      value = ex_to<numeric>(it->second);
      mag = GiNaC::abs(value);
      return value.is_real();
    }
  }
  // Constants, functions, fractional powers: evaluate as a whole.
  const ex v = GiNaC::evalf(e.subs(fpoint));
  if (!is_a<numeric>(v) || !ex_to<numeric>(v).is_real()) return false;
  value = ex_to<numeric>(v);
  mag = GiNaC::abs(value);
  return true;
}

}  // namespace

bool evaluate_with_magnitude(const ex& e, const GiNaC::exmap& point, int digits, numeric& value,
                             numeric& magnitude) {
  DigitsGuard guard(digits);
  try {
    GiNaC::exmap fpoint;
    for (const auto& [k, v] : point) fpoint[k] = GiNaC::evalf(v);
    if (eval_mag(e, fpoint, value, magnitude)) return true;
  } catch (const std::exception&) {
  }
  // Complex intermediates (which cancel) and the like: the plain evaluation.
  if (!evaluate_real(e, point, digits, value)) return false;
  magnitude = GiNaC::abs(value);
  return true;
}

std::vector<GiNaC::exmap> sample_points(const std::vector<GiNaC::symbol>& symbols,
                                        const SampleBoxes& boxes, int count, std::uint64_t seed) {
  // Large primes as denominators: exact rank / zero decisions at such points fail only on a
  // set of tiny measure.
  static const long primes[] = {1000003, 1000033, 1000037, 1000039, 1000081, 1000099};
  std::vector<GiNaC::exmap> out;
  std::uint64_t state = seed;
  // Two points near opposite corners of the box (distinct fractions per symbol, so no
  // diagonal x = y), where branch-dependent identities such as atan(tan x) = x break.
  for (int edge = 0; edge < 2 && edge < count; ++edge) {
    GiNaC::exmap pt;
    for (std::size_t j = 0; j < symbols.size(); ++j) {
      const Interval b = boxes.box(symbols[j]);
      const numeric frac =
          numeric(static_cast<long>(3 + 2 * (j % 16)), 101 + 2 * static_cast<long>(j / 16));
      pt[symbols[j]] = edge == 0 ? b.lo + (b.hi - b.lo) * frac : b.hi - (b.hi - b.lo) * frac;
    }
    out.push_back(pt);
  }
  for (int k = static_cast<int>(out.size()); k < count; ++k) {
    GiNaC::exmap pt;
    for (const auto& s : symbols) {
      const Interval b = boxes.box(s);
      const long p = primes[(splitmix(state) % 6)];
      const long j = 1 + static_cast<long>(splitmix(state) % static_cast<std::uint64_t>(p - 1));
      pt[s] = b.lo + (b.hi - b.lo) * numeric(j, p);
    }
    out.push_back(pt);
  }
  return out;
}

namespace {
// Magnitude against which "zero" is judged: the largest top-level term.
numeric term_scale(const ex& e, const GiNaC::exmap& pt, int digits) {
  numeric scale = 1;
  if (is_a<GiNaC::add>(e)) {
    for (std::size_t i = 0; i < e.nops(); ++i) {
      numeric v;
      if (evaluate_real(e.op(i), pt, digits, v) && GiNaC::abs(v) > scale) scale = GiNaC::abs(v);
    }
  }
  return scale;
}
}  // namespace

ZeroVerdict zero_test(const ex& e, const SampleBoxes& boxes, const ZeroTestOptions& opt) {
  if (e.is_zero()) return ZeroVerdict::proved;
  const auto syms = symbols_in(e);
  const auto points = sample_points(syms, boxes, opt.points, opt.seed);
  const numeric tol = numeric(10).power(numeric(-(opt.digits / 2)));
  int valid = 0;
  bool all_zero = true;
  bool tried_proof = false;
  // One point first: a clearly nonzero value settles it without symbolic work.
  for (std::size_t k = 0; k < points.size(); ++k) {
    numeric v;
    if (!evaluate_real(e, points[k], opt.digits, v)) continue;
    ++valid;
    if (GiNaC::abs(v) > tol * term_scale(e, points[k], opt.digits)) {
      all_zero = false;
      break;
    }
    if (!tried_proof) {
      tried_proof = true;
      if (proved_zero(e)) return ZeroVerdict::proved;
    }
  }
  if (!all_zero) return ZeroVerdict::nonzero;
  if (!tried_proof && proved_zero(e)) return ZeroVerdict::proved;
  return valid > 0 ? ZeroVerdict::numeric : ZeroVerdict::nonzero;
}

}  // namespace obsynth
