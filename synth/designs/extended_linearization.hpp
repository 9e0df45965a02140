// Extended linearization observer (Baumann-Rugh 1986; seed 001 §5, eq. 27-45), one output:
//
//   xh' = f(xh, u) + g(xh, u) + k(y) - k(h(xh))      (seed eq. 29, the injection called g there)
//
// Base point: the origin with u = u0 (the model's nominal input, else 0) must be an
// equilibrium, f(0) + g(0, u0) = 0 (seed: f(0, 0) = 0). The equilibrium family is
// parametrised by the output level, eps = y - h(0): x_eps, u_eps solve
//   f(x) + g(x, u) = 0,  h(x) = h(0) + eps,
// u being the model's first input (other inputs held at u0). By constraint (iii) this is a
// regular reparametrisation of the seed's family u = eps (dy_eps/deps != 0), and y_eps = eps
// makes y_{1 eps}^-1 the identity in eq. (38)-(40). The family is found in closed form when the
// equations can be solved one unknown at a time (each linear in it, with a coefficient that is
// nonzero at the base point), else as its power series from the implicit function theorem
// (Newton on truncated series, one order per iteration).
//
// Constraints at the base point, with A0 = d(f+g)/dx, B0 = d(f+g)/du, H0 = dh/dx:
//   (i) det A0 != 0;  (ii) (A0, H0) observable;  (iii) -H0 A0^-1 B0 != 0.
// The gain schedule c(eps) (= C(eps)^T, eq. 33) by Ackermann's formula,
//   c = p(A_eps) O_eps^-1 e_n,  O_eps = [H; H A; ...; H A^{n-1}] at the family,
// gives A_eps - c(eps) H_eps the prescribed characteristic polynomial p for every eps. The
// injection solves dk/dy(y_eps) = c(eps) (eq. 34): k(y) = int_0^{y - y0} c(e) de (eq. 40 with
// p = 1), in closed form when the project's integrator finds every antiderivative, else its
// Taylor polynomial of order m (eq. 42-45: (j + 1) k_j = c_j), so that dk~/dy(y_eps) agrees
// with c(eps) up to order m - 1 in eps.
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
  GiNaC::symbol eps{"eps"}, y{"y"};
  GiNaC::ex y0;                        // h at the base point (may hold free parameters)
  std::vector<GiNaC::numeric> x0, u0;  // base point
  bool family_closed = false;
  int family_order = 0;  // series order when not closed
  ExVec x_eps;           // x on the family (exact, or Taylor polynomial in eps)
  GiNaC::ex u_eps;       // the first input on the family
  std::vector<GiNaC::numeric> poles;
  bool poles_given = false;
  ExVec c_eps;  // gain schedule c(eps) = C(eps)^T
  bool injection_closed = false;
  int injection_order = 0;         // series order m when not closed
  std::string injection_reason;    // why the series was used
  ExVec injection;                 // k(y)
  double det_A0 = 0, dy_deps = 0;  // constraint (i), (iii) values
  std::size_t obs_rank = 0;        // constraint (ii)
};

// Runs the design (each call anew: its plan keeps the result). Throws UserError for bad
// options.
ExtendedLinearization extended_linearization(const Model& m, const DesignOptions& o);

}  // namespace obsynth
