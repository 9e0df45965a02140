#include "symbolic/integrate.hpp"

#include <fmt/format.h>

#include <map>
#include <vector>

#include "symbolic/expr_print.hpp"
#include "symbolic/symbolic.hpp"
#include "symbolic/zero_test.hpp"

namespace obsynth {

using GiNaC::ex;
using GiNaC::is_a;
using GiNaC::numeric;

namespace {

bool is_function(const ex& e, const char* name) {
  return is_a<GiNaC::function>(e) && GiNaC::ex_to<GiNaC::function>(e).get_name() == name;
}

// Polynomials in y whose coefficients are free of y: term by term.
std::optional<ex> integrate_polynomial(const ex& e, const GiNaC::symbol& y) {
  if (!e.is_polynomial(y)) return std::nullopt;
  const ex p = GiNaC::expand(e);
  ex r = 0;
  for (int k = 0; k <= p.degree(y); ++k) r += p.coeff(y, k) * GiNaC::pow(y, k + 1) / (k + 1);
  return r;
}

// ---------------------------------------------------------------------------------------
// The differential field Q(params)(y, generators): each atom of the integrand becomes a
// generator symbol whose derivative is a rational expression in y and the generators.
//   exp:  one base E = exp(u t) per y-dependent monomial t of the arguments (u the rational
//         gcd of t's coefficients), E' = u t' E; exp(b + sum c t) = exp(b) prod E^(c/u);
//   sin/cos: one pair S = sin(u B), C = cos(u B) per direction B, S' = u B' C,
//         C' = -u B' S; multiples by de Moivre; S^2 + C^2 = 1 is used to reduce C^2;
//   tanh/tan: H = tanh(a) with the sign of a fixed, H' = a' (1 - H^2) (tan: a' (1 + H^2));
//   atan(p): A' = p' / (1 + p^2); log(p): L' = p' / p.
// Arguments must be polynomials in y (no nested atoms of y).
enum class Kind { exp, sin, cos, tanh, tan, atan, log };

struct Generator {
  GiNaC::symbol sym;
  Kind kind;
  ex key;                   // exp: monomial t; sin/cos: direction B; others: the argument
  numeric unit = 1;         // exp, sin/cos: the base multiple u
  ex value, derivative{0};  // the atom, and d sym/dy in the field
};

class Field {
 public:
  explicit Field(const GiNaC::symbol& y) : y_(y) {}

  // Pass 1: the atoms of e and the units of their families. False (with why) outside the
  // supported set.
  bool scan(const ex& e, std::string& why);
  // Pass 2: generator values and derivatives, once every unit is known.
  void finish();
  ex to_field(const ex& e) const;  // atoms as generators
  ex to_atoms(const ex& e) const;  // generators as atoms
  ex derive(const ex& e) const;    // the derivation d/dy of the field
  const std::vector<Generator>& generators() const { return gens_; }
  const GiNaC::symbol& y() const { return y_; }

 private:
  GiNaC::symbol y_;
  std::vector<Generator> gens_;
  GiNaC::exmap back_;

  std::optional<std::size_t> find(Kind kind, const ex& key) const {
    for (std::size_t i = 0; i < gens_.size(); ++i)
      if (gens_[i].kind == kind && gens_[i].key.is_equal(key)) return i;
    return std::nullopt;
  }
  void note(Kind kind, const ex& key, const numeric& multiple) {
    if (const auto i = find(kind, key)) {
      gens_[*i].unit = rational_gcd(gens_[*i].unit, multiple);
      return;
    }
    const std::string prefix = kind == Kind::exp ? "E" : kind == Kind::sin ? "S" : "G";
    gens_.push_back(
        {GiNaC::symbol(prefix + std::to_string(gens_.size())), kind, key, GiNaC::abs(multiple), 0});
    if (kind == Kind::sin)
      gens_.push_back({GiNaC::symbol("C" + std::to_string(gens_.size())), Kind::cos, key,
                       GiNaC::abs(multiple), 0});
  }
  // Odd functions: the argument with its first term positive, and whether it was flipped.
  static std::pair<ex, bool> odd_key(const ex& arg) {
    const auto d = argument_direction(arg);
    if (!d) return {arg, false};
    const bool flip = d->multiple.is_negative();
    return {flip ? ex(GiNaC::expand(-arg)) : ex(GiNaC::expand(arg)), flip};
  }
  ex function_to_field(const ex& e) const;
};

bool Field::scan(const ex& e, std::string& why) {
  if (!e.has(y_) || e.is_equal(y_)) return true;
  if (is_a<GiNaC::add>(e) || is_a<GiNaC::mul>(e)) {
    for (std::size_t i = 0; i < e.nops(); ++i)
      if (!scan(e.op(i), why)) return false;
    return true;
  }
  if (is_a<GiNaC::power>(e)) {
    if (!is_a<numeric>(e.op(1)) || !GiNaC::ex_to<numeric>(e.op(1)).is_integer()) {
      why = fmt::format("{} is a non-integer power (outside the supported set)", to_string(e));
      return false;
    }
    return scan(e.op(0), why);
  }
  static const std::pair<const char*, Kind> known[] = {
      {"exp", Kind::exp}, {"sin", Kind::sin},   {"cos", Kind::sin}, {"tanh", Kind::tanh},
      {"tan", Kind::tan}, {"atan", Kind::atan}, {"log", Kind::log}};
  for (const auto& [name, kind] : known) {
    if (!is_function(e, name)) continue;
    const ex arg = GiNaC::expand(e.op(0));
    const auto terms = argument_terms(arg);
    if (!arg.is_polynomial(y_) || !terms) {
      why =
          fmt::format("the argument of {} is not a polynomial in {}", to_string(e), y_.get_name());
      return false;
    }
    if (kind == Kind::exp) {
      for (const auto& t : *terms)
        if (t.monomial.has(y_)) note(kind, t.monomial, t.coeff);
    } else if (kind == Kind::sin) {
      const auto d = argument_direction(arg);
      note(kind, d->key, d->multiple);
    } else {
      note(kind, kind == Kind::tanh || kind == Kind::tan ? odd_key(arg).first : arg, 1);
    }
    return true;
  }
  why = fmt::format("{} is outside the supported functions (exp, sin, cos, tanh, tan, atan, log)",
                    to_string(e));
  return false;
}

void Field::finish() {
  for (std::size_t i = 0; i < gens_.size(); ++i) {
    Generator& g = gens_[i];
    const ex arg = GiNaC::expand(g.unit * g.key);
    const ex da = arg.diff(y_);
    switch (g.kind) {
      case Kind::exp:
        g.value = GiNaC::exp(arg);
        g.derivative = da * g.sym;
        break;
      case Kind::sin:
        g.value = GiNaC::sin(arg);
        g.derivative = da * gens_[i + 1].sym;
        break;
      case Kind::cos:
        g.value = GiNaC::cos(arg);
        g.derivative = -da * gens_[i - 1].sym;
        break;
      case Kind::tanh:
        g.value = GiNaC::tanh(arg);
        g.derivative = da * (1 - g.sym * g.sym);
        break;
      case Kind::tan:
        g.value = GiNaC::tan(arg);
        g.derivative = da * (1 + g.sym * g.sym);
        break;
      case Kind::atan:
        g.value = GiNaC::atan(arg);
        g.derivative = da / (1 + arg * arg);
        break;
      case Kind::log:
        g.value = GiNaC::log(arg);
        g.derivative = da / arg;
        break;
    }
    back_[g.sym] = g.value;
  }
}

// cos(k a) + i sin(k a) = (C + i S)^k, k >= 0.
std::pair<ex, ex> de_moivre(const ex& S, const ex& C, long k) {
  ex c = 0, s = 0;
  numeric binom = 1;
  for (long j = 0; j <= k; ++j) {
    const ex term = binom * GiNaC::pow(C, k - j) * GiNaC::pow(S, j);
    const bool negative = (j / 2) % 2 == 1;
    (j % 2 == 0 ? c : s) += negative ? ex(-term) : term;
    binom = binom * (k - j) / (j + 1);
  }
  return {c, s};
}

ex Field::function_to_field(const ex& e) const {
  const ex arg = GiNaC::expand(e.op(0));
  if (is_function(e, "exp")) {
    ex out = 1, rest = 0;
    const auto terms = argument_terms(arg);  // scan() checked that they exist
    for (const auto& t : *terms) {
      if (!t.monomial.has(y_)) {
        rest += t.coeff * t.monomial;
        continue;
      }
      const Generator& g = gens_[*find(Kind::exp, t.monomial)];
      out *= GiNaC::pow(g.sym, t.coeff / g.unit);
    }
    return GiNaC::exp(rest) * out;
  }
  if (is_function(e, "sin") || is_function(e, "cos")) {
    const auto d = argument_direction(arg);
    const std::size_t i = *find(Kind::sin, d->key);
    const numeric k = d->multiple / gens_[i].unit;
    const auto [c, s] = de_moivre(gens_[i].sym, gens_[i + 1].sym, GiNaC::abs(k).to_long());
    if (is_function(e, "cos")) return c;
    return k.is_negative() ? -s : s;
  }
  if (is_function(e, "tanh") || is_function(e, "tan")) {
    const auto [key, flip] = odd_key(arg);
    const ex g = gens_[*find(is_function(e, "tanh") ? Kind::tanh : Kind::tan, key)].sym;
    return flip ? -g : g;
  }
  return gens_[*find(is_function(e, "atan") ? Kind::atan : Kind::log, arg)].sym;
}

ex Field::to_field(const ex& e) const {
  if (!e.has(y_) || e.is_equal(y_)) return e;
  if (is_a<GiNaC::function>(e)) return function_to_field(e);
  struct Recurse : GiNaC::map_function {
    const Field& field;
    explicit Recurse(const Field& f) : field(f) {}
    ex operator()(const ex& op) override { return field.to_field(op); }
  } recurse(*this);
  return e.map(recurse);
}

ex Field::to_atoms(const ex& e) const {
  return e.subs(back_);
}

ex Field::derive(const ex& e) const {
  ex d = e.diff(y_);
  for (const Generator& g : gens_)
    if (e.has(g.sym)) d += e.diff(g.sym) * g.derivative;
  return d;
}

bool has_generator(const ex& e, const Field& field) {
  for (const Generator& g : field.generators())
    if (e.has(g.sym)) return true;
  return false;
}

// ---------------------------------------------------------------------------------------
// Risch-Norman ansatz.

// c = monomial * coefficient, split by the field's variables.
using Coefficients = std::map<std::string, std::pair<ex, ex>>;  // text -> (monomial, coeff)

void add_coefficients(const ex& poly, const std::vector<GiNaC::symbol>& vars, const ex& scale,
                      Coefficients& out) {
  auto is_var_power = [&](const ex& f) {
    const ex base = is_a<GiNaC::power>(f) ? f.op(0) : f;
    for (const auto& v : vars)
      if (base.is_equal(v)) return true;
    return false;
  };
  auto take = [&](const ex& term) {
    ex mono = 1, coeff = 1;
    if (is_a<GiNaC::mul>(term)) {
      for (std::size_t i = 0; i < term.nops(); ++i)
        (is_var_power(term.op(i)) ? mono : coeff) *= term.op(i);
    } else {
      (is_var_power(term) ? mono : coeff) *= term;
    }
    auto [it, fresh] = out.try_emplace(to_string(mono), mono, coeff * scale);
    if (!fresh) it->second.second += coeff * scale;
  };
  if (is_a<GiNaC::add>(poly))
    for (std::size_t i = 0; i < poly.nops(); ++i) take(poly.op(i));
  else if (!poly.is_zero())
    take(poly);
}

// C^j -> C^(j mod 2) (1 - S^2)^(j div 2) for every sin/cos pair (a basis of the quotient).
ex reduce_trig(const ex& p, const Field& field) {
  ex r = GiNaC::expand(p);
  for (std::size_t i = 0; i + 1 < field.generators().size(); ++i) {
    const Generator& s = field.generators()[i];
    if (s.kind != Kind::sin) continue;
    const ex& C = field.generators()[i + 1].sym;
    if (r.degree(C) < 2) continue;
    ex acc = 0;
    for (int j = r.ldegree(C); j <= r.degree(C); ++j)
      acc += r.coeff(C, j) * GiNaC::pow(C, j % 2) * GiNaC::pow(1 - s.sym * s.sym, j / 2);
    r = GiNaC::expand(acc);
  }
  return r;
}

// A function of the ansatz: its value in atoms and its derivative in the field.
struct Candidate {
  ex value, derivative;
};

struct Denominator {
  ex content = 1;                           // free of y and the generators
  std::map<std::size_t, int> exp_shift;     // E_i^k factors (Laurent part of the numerator)
  std::vector<std::pair<ex, int>> factors;  // other irreducible factors and multiplicities
};

Denominator split_denominator(const ex& D, const Field& field,
                              const std::vector<GiNaC::symbol>& vars) {
  Denominator out;
  const ex fd = GiNaC::factor(D);
  const std::size_t count = is_a<GiNaC::mul>(fd) ? fd.nops() : 1;
  for (std::size_t i = 0; i < count; ++i) {
    const ex f = is_a<GiNaC::mul>(fd) ? fd.op(i) : fd;
    ex base = f;
    int mult = 1;
    if (is_a<GiNaC::power>(f) && is_a<numeric>(f.op(1))) {
      base = f.op(0);
      mult = static_cast<int>(GiNaC::ex_to<numeric>(f.op(1)).to_long());
    }
    if (!depends_on(base, vars)) {
      out.content *= f;
      continue;
    }
    bool is_exp_base = false;
    for (std::size_t g = 0; g < field.generators().size(); ++g)
      if (field.generators()[g].kind == Kind::exp && base.is_equal(field.generators()[g].sym)) {
        out.exp_shift[g] += mult;
        is_exp_base = true;
      }
    if (!is_exp_base) out.factors.push_back({base, mult});
  }
  return out;
}

constexpr std::size_t kMaxUnknowns = 160;

struct Range {
  int lo, hi;
};

// Exponent ranges of the ansatz numerator: y up to one degree more than the integrand's
// numerator; exp bases over the integrand's Laurent range; sin/cos up to the total trig
// degree with C reduced to degree <= 1; tanh/tan as in the integrand (their derivatives
// raise the degree); atan/log one more (y log y - y).
std::vector<Range> ansatz_ranges(const ex& numerator, const Field& field) {
  const auto& gens = field.generators();
  std::vector<Range> r{{0, numerator.degree(field.y()) + 1}};
  for (std::size_t i = 0; i < gens.size(); ++i) {
    const int lo = numerator.ldegree(gens[i].sym), hi = numerator.degree(gens[i].sym);
    switch (gens[i].kind) {
      case Kind::exp:
        r.push_back({std::min(lo, 0), std::max(hi, 0)});
        break;
      case Kind::sin: {
        const int total = hi + numerator.degree(gens[i + 1].sym);
        r.push_back({0, total});
        r.push_back({0, std::min(total, 1)});
        ++i;
        break;
      }
      case Kind::tanh:
      case Kind::tan:
        r.push_back({0, std::max(hi, 1)});
        break;
      default:
        r.push_back({0, hi + 1});
        break;
    }
  }
  return r;
}

// Logarithms (and arctangents) the antiderivative may need: of the denominator's factors and
// of the atoms' derivative denominators; log cosh for tanh, log|cos| for tan.
std::vector<Candidate> log_candidates(const Denominator& den, const Field& field) {
  std::vector<Candidate> out;
  const GiNaC::symbol& y = field.y();
  for (const auto& [base, mult] : den.factors) {
    const ex value = field.to_atoms(base);
    const bool y_only = !has_generator(base, field);
    if (y_only && base.degree(y) == 1)
      out.push_back({GiNaC::log(GiNaC::pow(value, 2)) / 2, field.derive(base) / base});
    else
      out.push_back({GiNaC::log(value), field.derive(base) / base});
    if (y_only && base.degree(y) == 2) {
      // atan((y + p/2)/w)/(a w) has derivative 1/base for base = a (y^2 + p y + s), w^2 > 0.
      const ex a = base.coeff(y, 2), p = base.coeff(y, 1) / a, s = base.coeff(y, 0) / a;
      const ex w2 = GiNaC::normal(s - p * p / 4);
      if (is_a<numeric>(w2) && GiNaC::ex_to<numeric>(w2).is_positive()) {
        const ex w = GiNaC::sqrt(w2);
        out.push_back({GiNaC::atan((y + p / 2) / w) / (a * w), 1 / base});
      }
    }
  }
  for (const Generator& g : field.generators()) {
    const ex da = g.key.diff(y);
    if (g.kind == Kind::atan)
      out.push_back({GiNaC::log(1 + g.key * g.key), 2 * g.key * da / (1 + g.key * g.key)});
    else if (g.kind == Kind::tanh)
      out.push_back({GiNaC::log(GiNaC::cosh(g.key)), da * g.sym});
    else if (g.kind == Kind::tan)
      out.push_back({GiNaC::log(GiNaC::pow(GiNaC::cos(g.key), 2)) / 2, -da * g.sym});
  }
  return out;
}

// The numerator monomials m / Dq of the ansatz, enumerated over the ranges.
std::vector<Candidate> polynomial_part(const std::vector<Range>& ranges, const ex& Dq,
                                       const std::vector<GiNaC::symbol>& vars, const Field& field) {
  std::vector<Candidate> out;
  std::vector<int> e(ranges.size());
  for (std::size_t i = 0; i < ranges.size(); ++i) e[i] = ranges[i].lo;
  while (true) {
    ex m = 1;
    for (std::size_t i = 0; i < ranges.size(); ++i) m *= GiNaC::pow(vars[i], e[i]);
    out.push_back({field.to_atoms(m) / field.to_atoms(Dq), field.derive(m / Dq)});
    std::size_t i = 0;
    while (i < ranges.size() && e[i] == ranges[i].hi) e[i] = ranges[i].lo, ++i;
    if (i == ranges.size()) break;
    ++e[i];
  }
  return out;
}

// g * den as a polynomial in the field's variables (trig-reduced), or nullopt when the
// common denominator does not clear g.
std::optional<ex> cleared(const ex& g, const ex& den, const Field& field,
                          const std::vector<GiNaC::symbol>& vars) {
  const ex nd = GiNaC::numer_denom(GiNaC::normal(g * den));
  if (depends_on(nd.op(1), vars)) return std::nullopt;
  return GiNaC::expand(reduce_trig(nd.op(0), field) / nd.op(1));
}

// The ansatz: its functions (with derivatives in the field) and a common denominator that
// clears every derivative and the integrand f.
struct Ansatz {
  std::vector<Candidate> basis;
  ex common = 1;
};

Integral solve_ansatz(const Ansatz& a, const ex& f, const Field& field,
                      const std::vector<GiNaC::symbol>& vars) {
  Coefficients equations;
  GiNaC::lst unknowns;
  for (std::size_t k = 0; k < a.basis.size(); ++k) {
    const GiNaC::symbol c("c" + std::to_string(k));
    unknowns.append(c);
    const auto g = cleared(a.basis[k].derivative, a.common, field, vars);
    if (!g) return {std::nullopt, "the ansatz's derivatives are not cleared by its denominator"};
    add_coefficients(*g, vars, c, equations);
  }
  const auto rhs = cleared(f, a.common, field, vars);
  if (!rhs) return {std::nullopt, "the integrand is not cleared by the ansatz's denominator"};
  add_coefficients(*rhs, vars, -1, equations);
  GiNaC::lst eqs;
  for (const auto& [text, mc] : equations) eqs.append(mc.second == 0);
  const ex sol = GiNaC::lsolve(eqs, unknowns, GiNaC::solve_algo::gauss);
  if (sol.nops() != unknowns.nops())
    return {std::nullopt,
            fmt::format("no antiderivative of the form P/Q + sum c log(v) with {} unknowns in "
                        "y and the atoms of the integrand",
                        a.basis.size())};
  GiNaC::exmap free;  // unknowns left free (the constant of integration) are set to 0
  for (std::size_t k = 0; k < unknowns.nops(); ++k) free[unknowns.op(k)] = 0;
  ex F = 0;
  for (std::size_t k = 0; k < a.basis.size(); ++k) {
    const ex ck = unknowns.op(k).subs(sol).subs(free);
    if (!ck.is_zero()) F += ck * a.basis[k].value;
  }
  return {F, ""};
}

Integral risch_norman(const ex& e, const GiNaC::symbol& y) {
  Field field(y);
  std::string why;
  if (!field.scan(e, why)) return {std::nullopt, why};
  field.finish();
  std::vector<GiNaC::symbol> vars{y};
  for (const auto& g : field.generators()) vars.push_back(g.sym);
  const ex f = GiNaC::normal(field.to_field(e));
  const ex nd = GiNaC::numer_denom(f);
  const Denominator den = split_denominator(nd.op(1), field, vars);
  ex laurent = nd.op(0);
  for (const auto& [g, k] : den.exp_shift) laurent *= GiNaC::pow(vars[g + 1], -k);
  const std::vector<Range> ranges = ansatz_ranges(GiNaC::expand(laurent), field);
  std::size_t size = 1;
  for (const Range& r : ranges) size *= static_cast<std::size_t>(r.hi - r.lo + 1);
  if (size > kMaxUnknowns)
    return {std::nullopt,
            fmt::format("the ansatz would need {} unknowns (limit {})", size, kMaxUnknowns)};
  // F = P / Dq + logs, Dq = prod v^(k-1) over the denominator's factors v^k.
  Ansatz a;
  ex Dq = 1;
  for (const auto& [base, mult] : den.factors) {
    Dq *= GiNaC::pow(base, mult - 1);
    a.common *= GiNaC::pow(base, mult);
  }
  for (std::size_t i = 0; i < field.generators().size(); ++i) {
    const Generator& g = field.generators()[i];
    if (g.kind == Kind::atan) a.common *= 1 + g.key * g.key;
    if (g.kind == Kind::log) a.common *= g.key;
    if (g.kind == Kind::exp) a.common *= GiNaC::pow(g.sym, -ranges[i + 1].lo);
  }
  a.basis = polynomial_part(ranges, Dq, vars, field);
  for (auto& c : log_candidates(den, field)) a.basis.push_back(std::move(c));
  return solve_ansatz(a, f, field, vars);
}

// ---------------------------------------------------------------------------------------
// Rational functions with rational coefficients.

bool numeric_poly(const ex& p, const GiNaC::symbol& y) {
  if (!p.is_polynomial(y)) return false;
  const ex e = GiNaC::expand(p);
  for (int k = 0; k <= e.degree(y); ++k)
    if (!is_a<numeric>(e.coeff(y, k))) return false;
  return true;
}

// ∫ 1/q^k for q = t^2 + w2 (w2 > 0) in t = y + p/2, by the reduction formula.
ex quadratic_power_integral(const ex& t, const ex& w2, long k) {
  const ex w = GiNaC::sqrt(w2);
  ex I = GiNaC::atan(t / w) / w;
  for (long j = 2; j <= k; ++j) {
    const ex q = t * t + w2;
    I = t / (2 * w2 * (j - 1) * GiNaC::pow(q, j - 1)) + numeric(2 * j - 3) / (2 * w2 * (j - 1)) * I;
  }
  return I;
}

// The factored denominator fq = lead * prod q_j^e_j with monic q_j of degree 1 or 2 in y
// (into factors, the constant into lead); false for a factor of higher degree.
bool monic_factors(const ex& fq, const GiNaC::symbol& y, std::vector<std::pair<ex, long>>& factors,
                   ex& lead) {
  auto take = [&](const ex& f) {
    ex base = f;
    long mult = 1;
    if (is_a<GiNaC::power>(f) && is_a<numeric>(f.op(1))) {
      base = f.op(0);
      mult = GiNaC::ex_to<numeric>(f.op(1)).to_long();
    }
    if (!base.has(y)) {
      lead *= f;
      return true;
    }
    const int deg = base.degree(y);
    if (deg > 2) return false;
    // Monic factor; the leading coefficient goes to `lead`.
    const ex lc = base.lcoeff(y);
    lead *= GiNaC::pow(lc, mult);
    factors.push_back({GiNaC::expand(base / lc), mult});
    return true;
  };
  if (!is_a<GiNaC::mul>(fq)) return take(fq);
  for (std::size_t i = 0; i < fq.nops(); ++i)
    if (!take(fq.op(i))) return false;
  return true;
}

// One partial fraction (A y + B)/q^k, A = 0 for linear q.
struct PartialFraction {
  ex q;
  long k;
  ex A, B;
};

// rem / Q as partial fractions over the factors (undetermined coefficients, solved exactly);
// nullopt when the linear system has no unique solution.
std::optional<std::vector<PartialFraction>> partial_fractions(
    const ex& rem, const ex& Q, const ex& lead, const std::vector<std::pair<ex, long>>& factors,
    const GiNaC::symbol& y) {
  // Ansatz: sum over factors and powers of (A y + B)/q^k (A = 0 for linear q).
  GiNaC::lst unknowns;
  ex ansatz = 0;
  std::vector<PartialFraction> terms;
  int counter = 0;
  for (const auto& [q, mult] : factors)
    for (long k = 1; k <= mult; ++k) {
      GiNaC::symbol A("pfA" + std::to_string(counter)), B("pfB" + std::to_string(counter));
      ++counter;
      const bool quad = q.degree(y) == 2;
      if (quad) unknowns.append(A);
      unknowns.append(B);
      const ex num = quad ? ex(A * y + B) : ex(B);
      terms.push_back({q, k, quad ? ex(A) : ex(0), B});
      ansatz += num * GiNaC::normal(Q / lead / GiNaC::pow(q, k));
    }
  const ex diff = GiNaC::expand(ansatz - rem / lead);
  GiNaC::lst eqs;
  for (int k = 0; k <= diff.degree(y); ++k) eqs.append(diff.coeff(y, k) == 0);
  const ex sol = GiNaC::lsolve(eqs, unknowns);
  if (sol.nops() != unknowns.nops()) return std::nullopt;
  for (auto& t : terms) {
    t.A = t.A.subs(sol);
    t.B = t.B.subs(sol);
  }
  return terms;
}

// Adds the integral of one partial fraction to result: log/power terms for a linear q, and
// log/atan/reduction terms for a quadratic one; false when q is reducible over R.
bool add_fraction_integral(const PartialFraction& t, const GiNaC::symbol& y, ex& result) {
  const ex &q = t.q, &A = t.A, &B = t.B;
  const long k = t.k;
  if (q.degree(y) == 1) {
    const ex root = q - y;  // q = y + root
    if (B.is_zero()) return true;
    if (k == 1)
      result += B * GiNaC::log(GiNaC::pow(y + root, 2)) / 2;
    else
      result += B * GiNaC::pow(y + root, 1 - k) / (1 - k);
    return true;
  }
  const ex p = q.coeff(y, 1), s = q.coeff(y, 0);
  const ex w2 = GiNaC::normal(s - p * p / 4);
  if (!is_a<numeric>(w2) || !GiNaC::ex_to<numeric>(w2).is_positive())
    return false;  // reducible over R
  // (A y + B)/q^k = (A/2)(2y + p)/q^k + (B - A p/2)/q^k
  if (!A.is_zero())
    result += k == 1 ? A / 2 * GiNaC::log(q) : A / 2 * GiNaC::pow(q, 1 - k) / (1 - k);
  const ex c = GiNaC::normal(B - A * p / 2);
  if (!c.is_zero()) result += c * quadratic_power_integral(y + p / 2, w2, k);
  return true;
}

// Rational functions with rational coefficients whose denominator factors over Q into linear
// and irreducible quadratic factors: polynomial part + partial fractions (undetermined
// coefficients, solved exactly) + log/atan/power terms. log|a y + b| is written
// log((a y + b)^2)/2 to stay real.
std::optional<ex> integrate_rational(const ex& e, const GiNaC::symbol& y) {
  const ex nd = GiNaC::numer_denom(GiNaC::normal(e));
  const ex P = GiNaC::expand(nd.op(0)), Q = GiNaC::expand(nd.op(1));
  if (!numeric_poly(P, y) || !numeric_poly(Q, y) || Q.degree(y) == 0) return std::nullopt;
  const ex poly = GiNaC::quo(P, Q, y), rem = GiNaC::rem(P, Q, y);
  ex result = 0;
  if (!poly.is_zero()) result += *integrate_polynomial(poly, y);
  if (rem.is_zero()) return result;
  // Factor Q: c * prod q_j^e_j.
  std::vector<std::pair<ex, long>> factors;
  ex lead = 1;
  if (!monic_factors(GiNaC::factor(Q), y, factors, lead)) return std::nullopt;
  const auto terms = partial_fractions(rem, Q, lead, factors, y);
  if (!terms) return std::nullopt;
  for (const auto& t : *terms)
    if (!add_fraction_integral(t, y, result)) return std::nullopt;
  return result;
}

}  // namespace

Integral integrate(const ex& e, const GiNaC::symbol& y) {
  std::optional<ex> r;
  std::string why;
  ex f;
  try {
    f = simplify(e);  // canonical atoms: exp(-y) exp(y) cancels before anything else
    if (!f.has(y)) return {f * y, ""};
    r = integrate_polynomial(f, y);
    if (!r) r = integrate_rational(f, y);
    if (!r) {
      Integral rn = risch_norman(f, y);
      r = rn.value;
      why = rn.reason;
    }
    if (!r) return {std::nullopt, why};
    const ex F = simplify(*r);
    if (zero_test(F.diff(y) - e, SampleBoxes{}) == ZeroVerdict::nonzero)
      return {std::nullopt, "the candidate failed the check by differentiation"};
    return {F, ""};
  } catch (const std::exception& err) {
    return {std::nullopt, fmt::format("integration failed: {}", err.what())};
  }
}

std::optional<ex> antiderivative(const ex& e, const GiNaC::symbol& y) {
  return integrate(e, y).value;
}

}  // namespace obsynth
