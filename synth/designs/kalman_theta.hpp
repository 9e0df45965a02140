// Kalman-like theta observer (Dufour-Flila-Hammouri, seed 002 eq. 7/10) for systems in the
// form z' = A(u) z + phi(u, z), y = C z (C = e_1, a_i(u) on the superdiagonal, phi
// triangular; with p > 1 outputs one such block per output, C picking each block's first
// coordinate, A(u) block diagonal and phi triangular by level: analysis/triangular_form.hpp's
// block form, in x or in z_{i,j} = L_f^{j-1} h_i with the observability indices as block sizes)
// that need not be uniformly observable (e.g. seed 002's example (4), where u = 0
// makes the system unobservable). The observer state is w = (zh, S) with S symmetric,
// stored as its packed upper triangle and kept positive definite:
//   zh' = A(u) zh + phi(u, zh) - S^-1 C^T (C zh - y),
//   S'  = -theta S - A(u)^T S - S A(u) + C^T C,
// the gain S^-1 C^T (y - C zh) applied by a Cholesky solve with S (never an inverse); S losing
// definiteness is Status::singular. Convergence needs a strongly persistent input
// (analysis/persistence.hpp, `obsynth check --input ... --horizon ...`).
// The form is taken directly in x when the model is already in it (triangular_in_x,
// analysis/persistence.hpp: w starts with the states, the estimate is zh itself); otherwise
// from the analysis' triangular form (analysis/triangular_form.hpp: z a permutation of the
// states, or z = (h, L_f h, ..., L_f^{n-1} h) with an explicit inverse x_of_z): the observer
// runs in zh, started from z_of_x(xh0), and its estimate is x_of_z(zh) (init and estimate
// functions of the spec). The verdict and report say which coordinates were used.
#pragma once

#include "designs/registry.hpp"

namespace obsynth {

Design kalman_theta_design();

}  // namespace obsynth
