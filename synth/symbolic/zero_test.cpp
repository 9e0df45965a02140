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

namespace {

constexpr int kDecades = 12;                // scaled points: box fractions 10^-1 .. 10^-12
constexpr std::size_t kMaxArguments = 8;    // arguments given points of their own
constexpr std::size_t kMaxVisits = 100000;  // nodes visited when collecting them

// A fraction in [10^-d, 10^(1-d)), with a large prime denominator.
numeric decade_fraction(int d, std::uint64_t& state) {
  const long p = 1000003;
  const long j = static_cast<long>(splitmix(state) % static_cast<std::uint64_t>(p));
  return (1 + numeric(9 * j, p)) / numeric(10).power(d);
}

// The box's point nearest 0, moved a fraction of the box towards one of its ends.
numeric towards_box(const Interval& b, const numeric& fraction, std::uint64_t& state) {
  const bool straddles = !b.lo.is_positive() && !b.hi.is_negative();
  const numeric anchor = straddles ? numeric(0) : b.lo.is_positive() ? b.lo : b.hi;
  const bool up = anchor == b.lo || (anchor != b.hi && (splitmix(state) & 1));
  return up ? anchor + (b.hi - anchor) * fraction : anchor - (anchor - b.lo) * fraction;
}

std::vector<GiNaC::exmap> decade_points(const std::vector<GiNaC::symbol>& symbols,
                                        const SampleBoxes& boxes, std::uint64_t& state) {
  std::vector<GiNaC::exmap> out;
  for (int d = 1; d <= kDecades; ++d) {
    GiNaC::exmap pt;
    for (const auto& s : symbols)
      pt[s] = towards_box(boxes.box(s), decade_fraction(d, state), state);
    out.push_back(pt);
  }
  return out;
}

bool is_steep_function(const ex& e) {
  if (!is_a<GiNaC::function>(e)) return false;
  const std::string name = ex_to<GiNaC::function>(e).get_name();
  return name == "sin" || name == "cos" || name == "tan" || name == "tanh" || name == "exp" ||
         name == "atan" || name == "log";
}

// Distinct arguments of the functions above, innermost last; stops after kMaxVisits nodes (a
// shared subtree is visited once per occurrence).
void collect_arguments(const ex& e, GiNaC::exset& seen, std::vector<ex>& args,
                       std::size_t& visits) {
  if (++visits > kMaxVisits || args.size() >= kMaxArguments) return;
  if (is_steep_function(e) && e.nops() == 1 && seen.insert(e.op(0)).second) args.push_back(e.op(0));
  for (std::size_t i = 0; i < e.nops(); ++i) collect_arguments(e.op(i), seen, args, visits);
}

// base with s moved so that the argument a (linear in s) takes a value of order one; false when
// that value of s lies outside its box or cannot be computed.
bool argument_point(const ex& a, const GiNaC::symbol& s, const GiNaC::exmap& base,
                    const SampleBoxes& boxes, std::uint64_t& state, int digits, GiNaC::exmap& out) {
  const ex slope_ex = a.diff(s);
  if (slope_ex.has(s)) return false;
  GiNaC::exmap at_zero = base;
  at_zero[s] = 0;
  numeric slope, offset;
  if (!evaluate_real(slope_ex, base, digits, slope) || slope.is_zero() ||
      !evaluate_real(a, at_zero, digits, offset))
    return false;
  const numeric target = (splitmix(state) & 1 ? 1 : -1) * decade_fraction(1, state) * 3;
  DigitsGuard guard(digits);
  const numeric v = (target - offset) / slope;
  const Interval b = boxes.box(s);
  if (v < b.lo || v > b.hi) return false;
  out = base;
  out[s] = v;
  return true;
}

}  // namespace

std::vector<GiNaC::exmap> scaled_points(const ex& e, const std::vector<GiNaC::symbol>& symbols,
                                        const SampleBoxes& boxes, std::uint64_t seed) {
  std::uint64_t state = seed ^ 0xdecade5ULL;
  std::vector<GiNaC::exmap> out = decade_points(symbols, boxes, state);
  if (symbols.empty()) return out;
  GiNaC::exset seen;
  std::vector<ex> args;
  std::size_t visits = 0;
  collect_arguments(e, seen, args, visits);
  const GiNaC::exmap base = sample_points(symbols, boxes, 3, seed ^ 0xa5a5ULL).back();
  const int digits = 20;
  for (const ex& a : args)
    for (const auto& s : symbols) {
      GiNaC::exmap pt;
      if (a.has(s) && argument_point(a, s, base, boxes, state, digits, pt)) out.push_back(pt);
    }
  return out;
}

ZeroTestResult zero_test_detailed(const ex& e, const SampleBoxes& boxes,
                                  const ZeroTestOptions& opt) {
  ZeroTestResult r;
  if (e.is_zero()) {
    r.verdict = ZeroVerdict::proved;
    return r;
  }
  const auto syms = symbols_in(e);
  const numeric tol = numeric(10).power(numeric(-(opt.digits / 2)));
  // True when e is clearly nonzero at pt (then pt is the witness); counts the zero points.
  auto nonzero_at = [&](const GiNaC::exmap& pt) {
    numeric v;
    if (!evaluate_real(e, pt, opt.digits, v)) return false;
    if (GiNaC::abs(v) > tol * term_scale(e, pt, opt.digits)) {
      r.witness = pt;
      r.witness_value = v;
      return true;
    }
    ++r.zero_points;
    return false;
  };
  bool tried_proof = false;
  // One point first: a clearly nonzero value settles it without symbolic work.
  for (const auto& pt : sample_points(syms, boxes, opt.points, opt.seed)) {
    if (nonzero_at(pt)) return r;
    if (!tried_proof && r.zero_points == 1) {
      tried_proof = true;
      if (proved_zero(e)) {
        r.verdict = ZeroVerdict::proved;
        return r;
      }
    }
  }
  if (!tried_proof && proved_zero(e)) {
    r.verdict = ZeroVerdict::proved;
    return r;
  }
  // Not proved: before calling it numerically zero, look where the expression has its scale.
  // The witness is the clearly nonzero point where it is largest: what a user would look at.
  bool found = false;
  for (const auto& pt : scaled_points(e, syms, boxes, opt.seed)) {
    numeric v;
    if (!evaluate_real(e, pt, opt.digits, v)) continue;
    if (GiNaC::abs(v) <= tol * term_scale(e, pt, opt.digits)) {
      ++r.zero_points;
    } else if (!found || GiNaC::abs(v) > GiNaC::abs(r.witness_value)) {
      found = true;
      r.witness = pt;
      r.witness_value = v;
    }
  }
  const bool numeric_zero = !found && r.zero_points > 0;
  r.verdict = numeric_zero ? ZeroVerdict::numeric : ZeroVerdict::nonzero;
  return r;
}

ZeroVerdict zero_test(const ex& e, const SampleBoxes& boxes, const ZeroTestOptions& opt) {
  return zero_test_detailed(e, boxes, opt).verdict;
}

}  // namespace obsynth
