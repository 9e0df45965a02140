// High-gain observer (Gauthier-Hammouri-Kupka; seed 002 eq. 3) for uniformly observable
// single-output systems. In the coordinates z = Phi(x) = (h, L_f h, ..., L_f^{n-1} h) the
// model reads z' = A z + phi(z, u), y = z_1 (output first, ones on the superdiagonal), with
//   phi_i = L_g L_f^{i-1} h (i < n),   phi_n = L_f^n h + L_g L_f^{n-1} h,
// and uniform observability (for input-affine models) means phi triangular: phi_i depends on
// z_1..z_i only. The observer zh' = A zh + phi(zh, u) + Delta_theta K (y - zh_1), with
// Delta_theta = diag(theta, ..., theta^n) and A - K C Hurwitz, is emitted in the original
// coordinates:
//   xh' = f(xh) + g(xh, u) + O(xh)^-1 Delta_theta K (y - h(xh)),   O = dPhi/dx,
// the gain applied by an LU solve with O(xh) (never an inverse); a singular O is
// Status::singular.
//
// Convergence (the usual Lyapunov argument, written out in high_gain.cpp): with
// eps_i = theta^{-(i-1)} e_i the error obeys eps' = theta (A - K C) eps + D^-1 (phi(zh) -
// phi(z)); with P solving (A - K C)^T P + P (A - K C) = -I and L a Lipschitz constant of phi
// in z (spectral norm of the entrywise bounds of d phi / d z), V = eps^T P eps decreases for
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
  ExVec Phi;                          // (h, L_f h, ..., L_f^{n-1} h)
  ExMatrix O;                         // dPhi/dx, row-major
  GiNaC::ex det;                      // det O (normalised)
  ExVec phi;                          // the nonlinearity of z' = A z + phi, as functions of (x, u)
  ExMatrix J;                         // d phi / d z = (d phi / dx) O^-1, as functions of (x, u)
  std::vector<std::string> failures;  // empty: the triangular form exists
};
HighGainStructure high_gain_structure(const Model& m);

// K with char(A - K C) = prod (s - pole) for A the upper shift, C = e_1:
// K_i = c_{n-i} of s^n + c_{n-1} s^{n-1} + ... + c_0.
std::vector<GiNaC::numeric> high_gain_K(const std::vector<GiNaC::numeric>& poles);

}  // namespace obsynth
