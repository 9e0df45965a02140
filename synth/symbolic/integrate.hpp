// A small, verified one-dimensional integrator: antiderivatives in one variable for the
// patterns the observer-form construction meets (polynomials, exp, sin, cos, their products
// with powers, 1/(a y^2 + c)). Every result is checked by differentiation.
#pragma once

#include <ginac/ginac.h>

#include <optional>

namespace obsynth {

std::optional<GiNaC::ex> antiderivative(const GiNaC::ex& e, const GiNaC::symbol& y);

}  // namespace obsynth
