// The James-Baras certificate (seed 000): the constants of (2.3) and (2.6), the radius rho of
// Theorem 2.1, delta of Corollary 2.1, and the uniform detectability test (3.3), over the
// model's domain box and input bounds.
//
// Conventions (seed 000 §2, with the transcription fixes of design.md / seeds/README.md):
//   A(x,u) = D_x (f + g)(x,u)            (n x n)
//   H(x)   = R^-1 Dh(x)                  (p x n; R acts as a standard deviation)
//   r0     = lambda_min(N N')            (N N' >= r0 I)
//   (3.3)  eta'(A + Lambda H) eta <= -alpha0 |eta|^2 on the box: alpha0 = -max lambda_max of
//          the symmetric part of A + Lambda H
//   (3.7)  q = ||Q0|| + (||N||^2 + ||Lambda||^2) / (2 alpha0)
//   (3.8)  p = (beta0/beta1) ||P0|| + (||H||^2 + ||Gamma||^2) / (2 beta0), P0 = Q0^-1,
//          beta0, beta1, ||Gamma|| = ||N|| beta1 of Lemma 3.1 as printed, minimised over sigma
//          on a grid (any sigma gives a valid p)
//   (2.3)  rho = r0 / (q^2 ||P0^(1/2)||) (sqrt(p) ||D^2 f|| + sqrt(q) ||R^-1||^2 ||Dh|| ||D^2
//   h||)^-1 (2.6)  delta = r0 / q^2 - 4 p ||Df|| - 4 ||R^-1||^2 ||Dh||^2     ("r_0/a^2" is r_0/q^2)
//   A term of (2.3)/(2.6) is omitted when the matching D^2 f or D^2 h is identically zero
//   (seed 000 below (2.6)); with both zero rho is infinite (the radius condition is void).
// ||D^2 f|| is bounded by the spectral norm of the stacked Hessians [H_1; ...; H_n] (so
// |D^2 f[a, b]| <= ||D^2 f|| |a| |b|), likewise ||D^2 h||.
//
// Every sup is taken over the domain box (states, inputs, free parameters), not over R^n as in
// the paper: the conclusions hold while the plant and the observer stay in the box. Each derived
// number is evaluated in outward-rounded ball arithmetic in the conservative direction (rho and
// delta are lower bounds, p and q upper bounds); it is `rigorous` when every input is.
#pragma once

#include <ginac/ginac.h>

#include <string>
#include <vector>

#include "certify/enclosure.hpp"
#include "foundation/report_row.hpp"
#include "front/model.hpp"

namespace obsynth::certify {

// Design parameters of (2.1)-(2.2). A 0 x 0 matrix (the member default) means the default:
//   Q0 = I_n, N = I_n, R = I_p, Lambda = 0 (n x p).
// Q0, N and R must be constant; Lambda may depend on the states, inputs and free parameters.
struct RiccatiParameters {
  GiNaC::matrix Q0 = GiNaC::matrix(0, 0), N = GiNaC::matrix(0, 0), R = GiNaC::matrix(0, 0),
                Lambda = GiNaC::matrix(0, 0);
};

// A derived number with its kind and, for a bound, its direction ("<=" upper, ">=" lower).
struct CertValue {
  double value = 0;
  BoundKind kind = BoundKind::rigorous;
  std::string direction;  // "<=", ">=", "=" (exact up to rounding)
};

struct RiccatiCertificate {
  std::string model;
  std::size_t n_states = 0, n_outputs = 0;
  Box box;
  RiccatiParameters params;                // with the defaults filled in
  std::vector<std::string> defaults_used;  // e.g. "Q0 = I"

  // Sup norms over the box.
  Bound Df, D2f, Dh, D2h, H, Lambda;
  bool D2f_zero = false, D2h_zero = false;  // identically zero: term omitted

  // Constant design matrices.
  CertValue r0, Q0_norm, P0_norm, P0_sqrt_norm, N_norm, Rinv_norm, R_min_eig;

  // (3.3) for the given Lambda.
  DefinitenessVerdict detectability;
  CertValue alpha0;

  CertValue q, p, sigma;  // sigma: the Lemma 3.1 parameter that gave p
  bool p_needed = false;  // p enters (2.3) or (2.6) only when D^2 f != 0

  CertValue rho;  // may be +inf
  CertValue delta;
  // delta recomputed with the sampled maxima in place of the rigorous sup bounds (and alpha0 from
  // the largest eigenvalue found): an estimate from above of the paper's delta, so delta_sampled
  // <= 0 says the failure is not an artefact of loose bounds.
  double delta_sampled = 0;

  bool theorem_2_1 = false;           // local: |x0 - m0| < rho
  bool corollary_2_1 = false;         // global
  bool rigorous = false;              // both verdicts rest on rigorous bounds only
  std::vector<std::string> failures;  // which condition failed and by how much
  std::string summary;
};

RiccatiCertificate riccati_certificate(const Model& m, const RiccatiParameters& params = {},
                                       const EnclosureBudget& budget = {});

// Key/value rows for a design report, every number labelled rigorous or sampled.
std::vector<ReportRow> riccati_certificate_rows(const RiccatiCertificate& c);

}  // namespace obsynth::certify
