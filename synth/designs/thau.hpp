// Thau observer (seed 001 §4, eq. 18-26) for x' = A x + B u + phi(x, u), y = C x (+ c0):
//   xh' = A xh + B u + phi(xh, u) + L (C xh + c0 - y)      (seed eq. 19: L (yh - y))
// with A + L C Hurwitz (pole placement), P solving (A + L C)^T P + P (A + L C) = -2 Q (eq. 21)
// and the certificate (eq. 26) sigma_min(Q) / sigma_max(P) > M, M a Lipschitz constant of phi
// in x on a convex region W (both x and xh in W). With the normalisation
// (A + L C)^T P' + P' (A + L C) = -Q (P' = P / 2) the same number reads
// sigma_min(Q) / (2 sigma_max(P')) - M: the margin of issue 9.
//
// The split is exact: A = dF/dx and B = dF/du at the expansion point x* (the origin when it is
// in the domain box, else the box centre; u* likewise; free parameters at their box centre),
// phi = F - A x - B u symbolically. M is bounded rigorously (Arb balls, certify/enclosure.hpp)
// and estimated by sampling, each labelled. The free choices (poles, Q) are searched for the
// largest sigma_min(Q)/sigma_max(P); when the condition fails on the whole domain, the largest
// sub-box W around x* (states scaled towards x*) on which it holds is searched. Past 4 states
// the search is budgeted (thau.cpp, kExhaustiveStates): Q = I (provably optimal), the poles
// searched, the sub-box chosen on sampled M and only it enclosed, under a work cap; what the
// enclosure cannot prove within it is reported as sampled.
#pragma once

#include <Eigen/Dense>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "designs/design_helpers.hpp"
#include "designs/registry.hpp"

namespace obsynth {

Design thau_design();

// The numbers behind the Thau verdict (for reports and tests).
struct ThauCertificate {
  std::string not_applicable;  // why the split or the placement does not exist; else empty
  std::vector<double> poles;   // eigenvalues of A + L C
  std::vector<double> L;       // n entries: the gain column of the output used
  std::size_t output = 0;      // that output
  double ratio = 0;            // sigma_min(Q) / sigma_max(P)
  double M_domain = 0, M_domain_sampled = 0;  // sup ||D_x phi||_2 on the domain
  double M_region = 0, M_region_sampled = 0;  // ... on the certified region W
  bool M_rigorous = false;                    // the region's M is a proven bound
  double margin_domain = 0, margin_region = 0;
  double scale = 1;                               // W = domain scaled by this towards x*
  std::vector<std::pair<double, double>> region;  // W's state ranges
  bool holds = false;                             // ratio > M on W
  std::size_t choices_tried = 0;
};
ThauCertificate thau_certificate(const Model& m, const DesignOptions& o = {});

// Numeric helpers shared by the Lyapunov-based designs (thau, kou).
namespace lyapunov_tools {

// The rational number exactly equal to the double v (finite).
GiNaC::numeric exact_of_double(double v);
// v rounded to `digits` significant decimal digits, as an exact rational.
GiNaC::numeric round_rational(double v, int digits = 6);
// v rounded to a multiple of 1/per_unit (per_unit a power of ten), exact.
GiNaC::numeric round_absolute(double v, double per_unit);
// Exact value of a numeric expression: rationals stay exact, anything else through evalf to
// double and exact_of_double. Throws UserError when not a real number.
GiNaC::numeric exact_value(const GiNaC::ex& e, const std::string& what);

// L (n x 1) with eig(A + L c) = roots of prod (s - pole) (seed 001 convention), by Ackermann's
// formula on the dual pair (A^T, c^T); nullopt when (c, A) is not observable.
std::optional<Eigen::VectorXd> place_poles(const Eigen::MatrixXd& A, const Eigen::RowVectorXd& c,
                                           const std::vector<double>& poles);
// The same in exact rational arithmetic (GiNaC); empty when (c, A) is not observable.
std::vector<GiNaC::numeric> place_poles_exact(const GiNaC::matrix& A, const GiNaC::matrix& c,
                                              const std::vector<GiNaC::numeric>& poles);
// P with AL^T P + P AL = -2 Q (seed 001 eq. 21); nullopt when the Kronecker system is singular.
std::optional<Eigen::MatrixXd> solve_lyapunov(const Eigen::MatrixXd& AL, const Eigen::MatrixXd& Q);
// Exact rational solution of the same equation; nullopt when singular.
std::optional<GiNaC::matrix> solve_lyapunov_exact(const GiNaC::matrix& AL, const GiNaC::matrix& Q);

// Deterministic sample points of a box: the corners (up to 2^10), the centre, then a Halton
// sequence, `count` points in all.
std::vector<std::vector<double>> box_samples(const std::vector<std::pair<double, double>>& ranges,
                                             std::size_t count);

// Deterministic Nelder-Mead minimisation; returns the best point found.
std::vector<double> nelder_mead(const std::function<double(const std::vector<double>&)>& f,
                                std::vector<double> x0, double step, int max_evals);

// Real pole sets tried by the searches: shapes -(1, 1.5, 2, ...), -(1, 2, 3, ...), and a
// repeated pole, each scaled by 1/4 ... 32.
std::vector<std::vector<double>> candidate_pole_sets(std::size_t n);

Eigen::MatrixXd to_eigen(const GiNaC::matrix& M);
std::string matrix_text(const Eigen::MatrixXd& M, int digits = 6);

}  // namespace lyapunov_tools

}  // namespace obsynth
