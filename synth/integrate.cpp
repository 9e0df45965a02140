#include "integrate.hpp"

#include "zero_test.hpp"

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
std::optional<ex> by_parts(const ex& coeff, long k, const ex& fn, const GiNaC::symbol& y, int depth) {
  const std::string name = GiNaC::ex_to<GiNaC::function>(fn).get_name();
  ex a, b;
  if (!linear_in(fn.op(0), y, a, b)) return std::nullopt;
  ex F;  // antiderivative of fn
  if (name == "exp") F = fn / a;
  else if (name == "sin") F = -GiNaC::cos(fn.op(0)) / a;
  else if (name == "cos") F = GiNaC::sin(fn.op(0)) / a;
  else return std::nullopt;
  if (k == 0) return coeff * F;
  // ∫ y^k fn = y^k F - k ∫ y^(k-1) F
  auto rest = integrate_sum(GiNaC::pow(y, k - 1) * F, y, depth + 1);
  if (!rest) return std::nullopt;
  return coeff * (GiNaC::pow(y, k) * F - k * *rest);
}

std::optional<ex> integrate_factor(const ex& coeff, const ex& f, const GiNaC::symbol& y, int depth) {
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
  if (others == 1 && k >= 0 && is_a<GiNaC::function>(other)) return by_parts(coeff, k, other, y, depth);
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

}  // namespace

std::optional<ex> antiderivative(const ex& e, const GiNaC::symbol& y) {
  std::optional<ex> r;
  try {
    r = integrate_sum(e, y, 0);
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
