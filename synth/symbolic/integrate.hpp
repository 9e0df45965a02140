// A verified one-dimensional integrator for the observer-form construction: antiderivatives
// in y of elementary integrands with coefficients in Q(parameters).
//  - polynomials in y: term by term;
//  - rational functions with rational coefficients: partial fractions (log, atan, powers);
//  - everything else in the supported set (y, exp, sin/cos, tanh, tan, atan and log of
//    polynomials in y): a Risch-Norman (parallel Risch) ansatz. The antiderivative is posited
//    as an unknown linear combination of monomials in y and the integrand's atoms over the
//    integrand's denominator, plus logarithms of the denominator's factors and of the atoms'
//    derivative denominators (log cosh for tanh, atan for irreducible quadratics); it is
//    differentiated, coefficients are matched and the linear system is solved exactly.
// Every result is verified by differentiation. When no antiderivative exists in the ansatz
// (exp(y^2), sin(y)/y are not elementary) the reason is returned instead.
#pragma once

#include <ginac/ginac.h>

#include <optional>
#include <string>

namespace obsynth {

struct Integral {
  std::optional<GiNaC::ex> value;  // an antiderivative, verified
  std::string reason;              // why none was found (empty when found)
};

Integral integrate(const GiNaC::ex& e, const GiNaC::symbol& y);

// integrate(e, y).value
std::optional<GiNaC::ex> antiderivative(const GiNaC::ex& e, const GiNaC::symbol& y);

}  // namespace obsynth
