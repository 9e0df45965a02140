// Canonical-form Luenberger observer (Krener-Isidori; seeds 001 §7, 003; design.md §1):
// error dynamics exactly linear in z = T(x).
//  - z realisation: zh' = A zh + l(u, y) + K (y - y0 - zh_n), xh = T^-1(zh). With u and y
//    held over a step this is w' = A_cl w + c, discretised exactly (Phi, Gamma) or by RK4.
//  - x realisation: xh' = f + g + [tau](xh) (l(u, y) - l(u, h(xh)) + K (y - h(xh))), needing
//    neither T nor T^-1 at run time.
#pragma once

#include <vector>

#include "designs/registry.hpp"

namespace obsynth {

Design canonical_design();

// Real poles -> K with the design.md convention (K_i = c_{i-1} of prod (s - pole)).
std::vector<GiNaC::numeric> gains_from_poles(const std::vector<GiNaC::numeric>& poles);
std::vector<GiNaC::numeric> default_poles(std::size_t n);

// h(x0) at the canonical form's base point: each block end z_{i,k_i} = y_i - y0_i.
ExVec outputs_at_base_point(const Analysis& a);

// A - K C of the block Brunovsky form (ones below the diagonal inside each block, -K in the
// column of each block's end), and its name in reports ("A - K e_n^T" for one output).
std::vector<std::vector<GiNaC::numeric>> closed_loop_matrix(const CanonicalForm& cf,
                                                            const std::vector<GiNaC::numeric>& K);
std::string closed_loop_text(const CanonicalForm& cf);

// x = T^-1(z) as a generated function: the elimination steps as let-bindings (straight-line
// code, never composed by substitution).
GeneratedFunction inverse_function(const Analysis& a);

// The canonical form's failures as reasons (empty when it applies).
std::vector<std::string> canonical_form_failures(const Analysis& a);

}  // namespace obsynth
