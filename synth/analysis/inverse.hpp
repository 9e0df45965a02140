// T^-1 as an elimination sequence (issue 6): x_{s1} = phi_1(z), x_{s2} = phi_2(z, x_{s1}), ...,
// each step solving one equation T_i(x) = z_i for one new state. The sequence is never
// expanded; each step is verified in its own equation.
#pragma once

#include <ginac/ginac.h>

#include <optional>

#include "analysis/canonical.hpp"
#include "foundation/budget.hpp"
#include "front/model.hpp"

namespace obsynth {

// Fills cf.T_inverse_steps, cf.T_inverse (their composition, unexpanded), the kind, note and
// verdict; numeric (a runtime Newton solve) when no elimination order is found.
void build_inverse(const Model& m, Budget& budget, const CanonicalOptions& opt, CanonicalForm& cf);

// Solves eq(xk) = 0 for xk when eq is linear in xk or in one invertible atom of xk (exp, log,
// atan, tanh); nullopt otherwise.
std::optional<GiNaC::ex> solve_for(const GiNaC::ex& eq, const GiNaC::symbol& xk);

// The elimination sequence in triangular order: at every step some unused equation contains
// exactly one unsolved state and is solvable for it. nullopt when there is no such order.
std::optional<std::vector<EliminationStep>> triangular_elimination(const ExVec& T, const Symbols& x,
                                                                   const Symbols& z);

}  // namespace obsynth
