// James-Baras Riccati observer (seed 000, eq. 2.1-2.2; design.md §3 `riccati`):
//
//   m' = f(m, u) + Q H(m)^T R^-1 (y - h(m))
//   Q' = A Q + Q A^T - Q H^T H Q + N N^T,    Q(0) = Q0 > 0,
//
// with A = D_x(f + g)(m, u) (input-dependent, derived symbolically) and H = R^-1 Dh(m), so
// R acts as a standard deviation: the gain is Q Dh^T R^-2 and the Riccati term
// Q Dh^T R^-2 Dh Q (an extended Kalman-Bucy filter with measurement covariance R^2 and
// process covariance N N^T). Several outputs are allowed.
//
// The observer state w = (m, Q) holds Q as its packed upper triangle (SymmetricBlock "Q",
// kept positive definite by the guarded RK4 step); the right-hand side computes only the
// upper triangle of Q'. Design parameters: --Q0, --N, --R (defaults I).
#pragma once

#include <ginac/ginac.h>

#include <string>
#include <vector>

#include "designs/registry.hpp"

namespace obsynth {

Design riccati_design();

// The design parameters of seed 000: Q0 (n x n, symmetric positive definite), N (n x n),
// R (p x p, symmetric positive definite), exact rationals. Shared with the certificate.
struct RiccatiParameters {
  GiNaC::matrix Q0, N, R;
  // Which of them were given (false: the default identity).
  bool Q0_given = false, N_given = false, R_given = false;
};

// Reads --Q0, --N, --R for a model with n states and p outputs. A matrix option is given as
// n values (the diagonal), n*n values (row-major full matrix) or one value (a multiple of I).
// Throws UserError naming the option for a wrong count, a non-symmetric or not positive
// definite Q0 or R.
RiccatiParameters riccati_parameters(std::size_t n, std::size_t p, const DesignOptions& o);

// Whether a symmetric matrix of exact rationals is positive definite (all leading principal
// minors > 0, Sylvester's criterion, exact).
bool exact_positive_definite(const GiNaC::matrix& M);

}  // namespace obsynth
