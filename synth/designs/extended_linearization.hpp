// Extended linearization observer (Baumann-Rugh 1986; seed 001 §5, eq. 27-45), p outputs:
//
//   xh' = f(xh, u) + g(xh, u) + k(y) - k(h(xh))      (seed eq. 29, the injection called g there)
//
// Base point: the origin with u = u0 (the model's nominal input, else 0) must be an
// equilibrium, f(0) + g(0, u0) = 0 (seed: f(0, 0) = 0). The equilibrium family is
// parametrised by the level of one output y_k, eps = y_k - h_k(0): x_eps, u_eps solve
//   f(x) + g(x, u) = 0,  h_k(x) = h_k(0) + eps,
// u being the model's first input (other inputs held at u0), y_k the first output with
// dy_k,eps/deps != 0 (constraint (iii); the seed's "without loss of generality" before eq. 38).
// This is a regular reparametrisation of the seed's family u = eps, and y_k,eps = eps makes
// y_{k eps}^-1 the identity in eq. (38)-(40). The family is found in closed form when the
// equations can be solved one unknown at a time (each linear in it, with a coefficient that is
// nonzero at the base point), else as its power series from the implicit function theorem
// (Newton on truncated series, one order per iteration).
//
// Constraints at the base point, with A0 = d(f+g)/dx, B0 = d(f+g)/du, H0 = dh/dx:
//   (i) det A0 != 0;  (ii) (A0, H0) observable;  (iii) -H0 A0^-1 B0 != 0.
// The gain schedule C(eps)^T (eq. 33) places the eigenvalues of A_eps - C(eps)^T H_eps. For one
// output, Ackermann's formula c = p(A_eps) O_eps^-1 e_n, O_eps = [H; H A; ...; H A^{n-1}] at the
// family. For p outputs Ackermann's formula is not unique; the classic reduction to one output
// is used: C^T = L0 + c(eps) w^T with a constant pre-gain L0 (zero unless A0 is not cyclic) and
// a combination w, so that (A_eps - L0 H_eps, w^T H_eps) is observable, and c(eps) by Ackermann
// on that pair. The injection solves dk/dy(y_eps) = C(eps)^T (eq. 34) by eq. (40), with s =
// y_k - y0_k:
//   k(y) = G(s) + sum_{j != k} c_j(s) (y_j - y_j,eps(s)),  G(s) = int_0^s C(e)^T dy_e/de de,
// in closed form when the project's integrator finds every antiderivative, else with the Taylor
// polynomials of order m of G, c_j and y_j,eps (eq. 42-45), so that dk~/dy(y_eps) agrees with
// C(eps)^T up to order m - 1 in eps.
#pragma once

#include <ginac/ginac.h>

#include <optional>
#include <string>
#include <vector>

#include "designs/registry.hpp"

namespace obsynth {

Design extended_linearization_design();

// The design's results, for tests and reports. Expressions are in the model's symbols, eps
// and the output symbol y; free parameters stay symbolic.
struct ExtendedLinearization {
  std::vector<std::string> failures;  // why it does not apply (empty: it does)
  std::vector<std::string> notes;     // constraint values and choices, with numbers
  GiNaC::symbol eps{"eps"};
  std::vector<GiNaC::symbol> y;        // the outputs: "y" (p = 1), else "y1", "y2", ...
  ExVec y0;                            // h at the base point (may hold free parameters)
  std::size_t level_output = 0;        // k: eps = y_k - y0_k parametrises the family
  std::vector<GiNaC::numeric> x0, u0;  // base point
  bool family_closed = false;
  int family_order = 0;  // series order when not closed
  ExVec x_eps;           // x on the family (exact, or Taylor polynomial in eps)
  GiNaC::ex u_eps;       // the first input on the family
  std::vector<GiNaC::numeric> poles;
  bool poles_given = false;
  // The gain schedule C(eps)^T = L0 + c(eps) w^T: for p > 1, a constant pre-gain L0 (n x p, by
  // rows; zero unless A0 - L0 H0 must be made cyclic) and a combination w of the outputs with
  // (A_eps - L0 H_eps, w^T H_eps) observable; c(eps) by single-output Ackermann on that pair.
  // For p = 1: L0 = 0, w = 1.
  std::vector<std::vector<GiNaC::numeric>> pre_gain;
  std::vector<GiNaC::numeric> combination;
  ExVec c_eps;              // c(eps)
  std::vector<ExVec> gain;  // the columns of C(eps)^T: gain[j] = L0 e_j + w_j c(eps)
  bool injection_closed = false;
  int injection_order = 0;            // series order m when not closed
  std::string injection_reason;       // why the series was used
  ExVec injection;                    // k(y)
  double det_A0 = 0, dy_deps = 0;     // constraint (i), (iii) values (dy_k/deps for y_k)
  std::vector<double> output_slopes;  // dy_eps/deps = -H0 A0^-1 B0, one per output
  std::size_t obs_rank = 0;           // constraint (ii)
};

// Runs the design (each call anew: its plan keeps the result). Throws UserError for bad
// options.
ExtendedLinearization extended_linearization(const Model& m, const DesignOptions& o);

}  // namespace obsynth
