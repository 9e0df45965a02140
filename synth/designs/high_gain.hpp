// High-gain observer (Gauthier-Hammouri-Kupka; seed 002 eq. 3) for uniformly observable
// systems, with p >= 1 outputs. With the observability indices k_1..k_p (sum n; the analysis'
// rows added k-major), the coordinates are one chain per output, output first in each block:
//   z = Phi(x) = (h_1, L_f h_1, ..., L_f^{k_1-1} h_1, ..., h_p, ..., L_f^{k_p-1} h_p)
// (p = 1: z = (h, L_f h, ..., L_f^{n-1} h)). Write z_{i,j} = L_f^{j-1} h_i, j = 1..k_i (its
// level is j). The model reads z' = A z + phi(z, u), y_i = z_{i,1}, with A = blockdiag(A_i),
// A_i the k_i x k_i upper shift, and
//   phi_{i,j} = L_g L_f^{j-1} h_i (j < k_i),   phi_{i,k_i} = L_f^{k_i} h_i + L_g L_f^{k_i-1} h_i.
// The observer zh' = A zh + phi(zh, u) + Delta_theta K (y - C zh), with Delta_theta =
// blockdiag(diag(theta, ..., theta^{k_i})), K = blockdiag(K_i), A_i - K_i e_1^T Hurwitz and
// C z = (z_{1,1}, ..., z_{p,1}), is emitted in the original coordinates:
//   xh' = f(xh) + g(xh, u) + O(xh)^-1 Delta_theta K (y - h(xh)),   O = dPhi/dx,
// the gain applied by an LU solve with O(xh) (never an inverse); a singular O is
// Status::singular.
//
// The structural condition checked (block triangularity by level):
//   d phi_{i,j} / d z_{l,m} = 0 for every block l and every m > j,
// i.e. phi_{i,j} depends only on z_{l,1..j} of every block l (p = 1: phi_i depends on z_1..z_i,
// the Gauthier-Kupka triangular form; equal indices: the block-triangular form of Hammouri &
// Farza, ESAIM COCV 9 (2003), and Farza, M'Saad & Rossignol, Automatica 40 (2004); unequal
// indices: the same level condition, which is what the proof below uses). The verdict names
// each entry that breaks it, with its value.
//
// Convergence (the usual Lyapunov argument, written out in high_gain.cpp): with the scaled error
// eps_{i,j} = theta^{-(j-1)} e_{i,j} the error obeys eps' = theta (A - K C) eps + D^-1 (phi(zh)
// - phi(z)), D = blockdiag(diag(1, theta, ..., theta^{k_i-1})); the entry (i,j),(l,m) of the
// nonlinear term carries theta^{m-j} d phi_{i,j}/d z_{l,m}, bounded for theta >= 1 exactly when
// the condition above holds. With P solving (A - K C)^T P + P (A - K C) = -I (block diagonal:
// lambda_max(P) is the largest over the blocks) and L a Lipschitz constant of phi in z (spectral
// norm of the entrywise bounds of d phi / d z), V = eps^T P eps decreases for
//   theta > theta* = max(1, 2 lambda_max(P) L).
#pragma once

#include <string>
#include <vector>

#include "designs/registry.hpp"

namespace obsynth {

Design high_gain_design();

// The structure the design rests on, computed from the model (independently of the analysis'
// canonical-form stages).
struct HighGainStructure {
  std::vector<std::size_t> blocks;    // k_1..k_p (p = 1: {n})
  ExVec Phi;                          // the chains, block by block (see above)
  ExMatrix O;                         // dPhi/dx, row-major
  GiNaC::ex det;                      // det O (normalised)
  ExVec phi;                          // the nonlinearity of z' = A z + phi, as functions of (x, u)
  ExMatrix J;                         // d phi / d z = (d phi / dx) O^-1, as functions of (x, u)
  std::vector<std::string> failures;  // empty: the triangular form exists
};
// indices: the observability indices k_1..k_p (Observability::indices); empty for p = 1 means
// {n}.
HighGainStructure high_gain_structure(const Model& m, std::vector<std::size_t> indices = {});

// Rows of z by block and level: block_of, level_of, z_label (analysis/triangular_form.hpp).
// "z = (h, L_f h, ..., L_f^{n-1} h)", or the block chains with their indices.
std::string high_gain_coordinates(const std::vector<std::size_t>& blocks);

// K with char(A - K C) = prod (s - pole) for A the upper shift, C = e_1:
// K_i = c_{n-i} of s^n + c_{n-1} s^{n-1} + ... + c_0.
std::vector<GiNaC::numeric> high_gain_K(const std::vector<GiNaC::numeric>& poles);
// Per block: poles split consecutively by the block sizes, K the blocks' K concatenated.
std::vector<GiNaC::numeric> high_gain_K(const std::vector<GiNaC::numeric>& poles,
                                        const std::vector<std::size_t>& blocks);

}  // namespace obsynth
