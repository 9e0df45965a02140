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
// atan, tanh); nullopt otherwise. With `roots`, also when eq is linear in one square root
// sqrt(a xk + b) of an affine argument; *root_atom and *root then receive that root and its
// value w (xk = (w^2 - b) / a on the branch w >= 0), otherwise 0.
std::optional<GiNaC::ex> solve_for(const GiNaC::ex& eq, const GiNaC::symbol& xk, bool roots = false,
                                   GiNaC::ex* root_atom = nullptr, GiNaC::ex* root = nullptr);

// The elimination sequence in triangular order: at every step some unused equation contains
// exactly one unsolved state and is solvable for it. nullopt when there is no such order.
// `roots`: square roots may be inverted (EliminationStep::root), for the triangular forms,
// which substitute the root's value for the root itself (analysis/triangular_form.cpp).
std::optional<std::vector<EliminationStep>> triangular_elimination(const ExVec& T, const Symbols& x,
                                                                   const Symbols& z,
                                                                   bool roots = false);

}  // namespace obsynth
