#include "symbolic/integrate.hpp"

#include "symbolic/zero_test.hpp"

namespace obsynth {

using GiNaC::ex;
using GiNaC::is_a;
using GiNaC::numeric;

namespace {

// arg = a*y + b with a, b free of y and a != 0.
bool linear_in(const ex& arg, const GiNaC::symbol& y, ex& a, ex& b) {
  const ex e = GiNaC::expand(arg);
  if (!e.has(y)) return false;
  a = e.diff(y);
  if (a.has(y)) return false;
  b = GiNaC::expand(e - a * y);
  return true;
}

std::optional<ex> integrate_factor(const ex& coeff, const ex& f, const GiNaC::symbol& y, int depth);

// Splits a term into (factor free of y) * (y-dependent part).
void split_term(const ex& term, const GiNaC::symbol& y, ex& c, ex& dep) {
  c = 1;
  dep = 1;
  if (is_a<GiNaC::mul>(term)) {
    for (std::size_t i = 0; i < term.nops(); ++i) {
      if (term.op(i).has(y))
        dep *= term.op(i);
      else
        c *= term.op(i);
    }
  } else if (term.has(y)) {
    dep = term;
  } else {
    c = term;
  }
}

std::optional<ex> integrate_term(const ex& term, const GiNaC::symbol& y, int depth) {
  ex c, dep;
  split_term(term, y, c, dep);
  if (!dep.has(y)) return c * dep * y;
  return integrate_factor(c, dep, y, depth);
}

std::optional<ex> integrate_sum(const ex& e, const GiNaC::symbol& y, int depth) {
  if (depth > 12) return std::nullopt;
  const ex x = GiNaC::expand(e);
  ex acc = 0;
  if (is_a<GiNaC::add>(x)) {
    for (std::size_t i = 0; i < x.nops(); ++i) {
      auto t = integrate_term(x.op(i), y, depth);
      if (!t) return std::nullopt;
      acc += *t;
    }
    return acc;
  }
  return integrate_term(x, y, depth);
}

// y^k (k >= 0 integer) times an exponential/trigonometric factor of a linear argument.
std::optional<ex> by_parts(const ex& coeff, long k, const ex& fn, const GiNaC::symbol& y,
                           int depth) {
  const std::string name = GiNaC::ex_to<GiNaC::function>(fn).get_name();
  ex a, b;
  if (!linear_in(fn.op(0), y, a, b)) return std::nullopt;
  ex F;  // antiderivative of fn
  if (name == "exp")
    F = fn / a;
  else if (name == "sin")
    F = -GiNaC::cos(fn.op(0)) / a;
  else if (name == "cos")
    F = GiNaC::sin(fn.op(0)) / a;
  else
    return std::nullopt;
  if (k == 0) return coeff * F;
  // ∫ y^k fn = y^k F - k ∫ y^(k-1) F
  auto rest = integrate_sum(GiNaC::pow(y, k - 1) * F, y, depth + 1);
  if (!rest) return std::nullopt;
  return coeff * (GiNaC::pow(y, k) * F - k * *rest);
}

std::optional<ex> integrate_factor(const ex& coeff, const ex& f, const GiNaC::symbol& y,
                                   int depth) {
  // Collect y^k and at most one other factor.
  long k = 0;
  ex other = 1;
  int others = 0;
  auto take = [&](const ex& fac) {
    if (fac == y) {
      ++k;
      return;
    }
    if (is_a<GiNaC::power>(fac) && fac.op(0) == y && is_a<numeric>(fac.op(1)) &&
        GiNaC::ex_to<numeric>(fac.op(1)).is_integer()) {
      k += GiNaC::ex_to<numeric>(fac.op(1)).to_long();
      return;
    }
    other *= fac;
    ++others;
  };
  if (is_a<GiNaC::mul>(f))
    for (std::size_t i = 0; i < f.nops(); ++i) take(f.op(i));
  else
    take(f);
  if (others == 0) {
    if (k == -1) return std::nullopt;  // log|y| is outside the function set's real branch
    return coeff * GiNaC::pow(y, k + 1) / (k + 1);
  }
  if (others == 1 && k >= 0 && is_a<GiNaC::function>(other))
    return by_parts(coeff, k, other, y, depth);
  // 1/(a y^2 + c) with a, c > 0 numbers
  if (others == 1 && k == 0 && is_a<GiNaC::power>(other) && other.op(1) == -1) {
    const ex q = GiNaC::expand(other.op(0));
    if (q.is_polynomial(y) && q.degree(y) == 2 && q.coeff(y, 1).is_zero()) {
      const ex a = q.coeff(y, 2), c = q.coeff(y, 0);
      if (is_a<numeric>(a) && is_a<numeric>(c) && GiNaC::ex_to<numeric>(a).is_positive() &&
          GiNaC::ex_to<numeric>(c).is_positive())
        return coeff * GiNaC::atan(y * GiNaC::sqrt(a / c)) / GiNaC::sqrt(a * c);
    }
  }
  return std::nullopt;
}

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
  if (!poly.is_zero()) {
    auto pi = integrate_sum(poly, y, 0);
    if (!pi) return std::nullopt;
    result += *pi;
  }
  if (rem.is_zero()) return result;
  // Factor Q: c * prod q_j^e_j.
  const ex fq = GiNaC::factor(Q);
  std::vector<std::pair<ex, long>> factors;
  ex lead = 1;
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
  if (is_a<GiNaC::mul>(fq)) {
    for (std::size_t i = 0; i < fq.nops(); ++i)
      if (!take(fq.op(i))) return std::nullopt;
  } else if (!take(fq)) {
    return std::nullopt;
  }
  // Ansatz: sum over factors and powers of (A y + B)/q^k (A = 0 for linear q).
  GiNaC::lst unknowns;
  ex ansatz = 0;
  std::vector<std::tuple<ex, long, ex, ex>> terms;  // q, k, A, B
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
  for (const auto& [q, k, A0, B0] : terms) {
    const ex A = A0.subs(sol), B = B0.subs(sol);
    if (q.degree(y) == 1) {
      const ex root = q - y;  // q = y + root
      if (B.is_zero()) continue;
      if (k == 1)
        result += B * GiNaC::log(GiNaC::pow(y + root, 2)) / 2;
      else
        result += B * GiNaC::pow(y + root, 1 - k) / (1 - k);
      continue;
    }
    const ex p = q.coeff(y, 1), s = q.coeff(y, 0);
    const ex w2 = GiNaC::normal(s - p * p / 4);
    if (!is_a<numeric>(w2) || !GiNaC::ex_to<numeric>(w2).is_positive())
      return std::nullopt;  // reducible over R
    // (A y + B)/q^k = (A/2)(2y + p)/q^k + (B - A p/2)/q^k
    if (!A.is_zero())
      result += k == 1 ? A / 2 * GiNaC::log(q) : A / 2 * GiNaC::pow(q, 1 - k) / (1 - k);
    const ex c = GiNaC::normal(B - A * p / 2);
    if (!c.is_zero()) result += c * quadratic_power_integral(y + p / 2, w2, k);
  }
  return result;
}

}  // namespace

std::optional<ex> antiderivative(const ex& e, const GiNaC::symbol& y) {
  std::optional<ex> r;
  try {
    r = integrate_sum(e, y, 0);
    if (!r) r = integrate_rational(e, y);
  } catch (const std::exception&) {
    return std::nullopt;
  }
  if (!r) return std::nullopt;
  const ex F = GiNaC::normal(*r);
  SampleBoxes boxes;
  if (zero_test(F.diff(y) - e, boxes) == ZeroVerdict::nonzero) return std::nullopt;
  return F;
}

}  // namespace obsynth
