// Lie derivatives, Jacobians and Lie brackets (design.md §1 conventions):
//   L_f phi = dphi * f,   [a, b] = (db/dx) a - (da/dx) b,   ad_f b = [f, b].
#pragma once

#include <ginac/ginac.h>

#include <vector>

#include "foundation/budget.hpp"
#include "foundation/expr.hpp"

namespace obsynth {

ExMatrix jacobian(const ExVec& field, const Symbols& x);
GiNaC::ex lie_derivative(const GiNaC::ex& phi, const ExVec& field, const Symbols& x);
// [a, b] given the Jacobians of a and b (callers cache them).
ExVec lie_bracket(const ExVec& a, const ExMatrix& da, const ExVec& b, const ExMatrix& db);
ExVec lie_bracket(const ExVec& a, const ExVec& b, const Symbols& x);

// L_f^k h and its simplified gradient for k = 0..count-1. The gradient of L_f^k h, dotted
// with f, gives L_f^{k+1} h: one differentiation pass serves both the chain and the rows of
// the observability matrix.
struct LieChain {
  ExVec derivatives;   // L_f^k h
  ExMatrix gradients;  // d(L_f^k h)/dx
};
LieChain lie_chain_with_gradients(const GiNaC::ex& h, const ExVec& f, const Symbols& x,
                                  std::size_t count, const Budget* budget = nullptr);

ExVec simplified(const ExVec& v);

}  // namespace obsynth
