// Seed 002 (Dufour, Flila, Hammouri): the normal form z' = A(u) z + phi(u, z), y = C z
// (output first, a_i(u) on the superdiagonal, phi_i depending on z_1..z_i, C = e_1), detected
// when the model is already in that form in x, and the strong persistence of a given input:
// With p > 1 outputs C selects each block's first coordinate (the block form of
// analysis/triangular_form.hpp), Psi and the Gramian use that C, and ii) compares the levels:
// Gamma_rr / Gamma_cc for level(c) <= level(r) (p = 1: j <= i). Seed 002 states the Definition for
// one output; this is its direct reading for the block form, not a theorem of the seed.
//   Psi(t, theta) = int_0^t e^{-theta (t-s)} Phi_u(s,t)^T C^T C Phi_u(s,t) ds, obtained as the
//     solution of Psi' = -theta Psi - A^T Psi - Psi A + C^T C, Psi(0) = 0 (eq. 8 with S(0) = 0);
//   Gamma(t, theta) = diag(Psi_11, ..., Psi_nn) (eq. 9);
//   the Gramian (6) G(u, a, b) = int_a^b Phi_u(t,a)^T C^T C Phi_u(t,a) dt.
// Definition (strong persistence): there are theta_0, t_0 such that for all theta > theta_0,
// t >= t_0: i) Gamma invertible and Gamma <= alpha(theta) Psi with alpha(theta)/theta -> 0;
// ii) Gamma_ii / Gamma_jj <= gamma for 1 <= j <= i.
// Checked numerically along the input on [t_0, horizon] for a range of theta: a verdict from
// samples, labelled so.
#pragma once

#include <ginac/ginac.h>

#include <nlohmann/json.hpp>

#include <optional>
#include <string>
#include <vector>

#include "front/model.hpp"

namespace obsynth {

// The model in seed 002's form directly in x: F(x, u) = A(u) x + phi(u, x), y = x_1.
// With p > 1 outputs (analysis/triangular_form.hpp's block form): y_1 = x1 and each y_i a later
// state starting its block, a zero between blocks, phi triangular by level.
struct TriangularInX {
  ExVec a;                          // a_1(u) .. a_{n-1}(u): superdiagonal
  ExVec phi;                        // phi_i(u, x_1..x_i) (phi_n may depend on every state)
  std::vector<std::size_t> blocks;  // block sizes (empty: one block)
};
// nullopt with `why` set when the model is not in that form in x.
std::optional<TriangularInX> triangular_in_x(const Model& m, std::string* why);

// The Theorem's other hypothesis: phi(u, z) Lipschitz in z. On the compact domain box a phi
// that is continuously differentiable there is Lipschitz on it (the usual reading of "globally
// Lipschitz" for a plant that stays in its box), so what can fail is a denominator of some
// d phi_i / d z_j that vanishes in the box (taken back to x through z_of_x):
//  proved  - every z-dependent denominator factor proved nonzero on the box (zeros_in_box);
//  fails   - one vanishes in the box (proved): phi is undefined there and, near that set, its
//            derivative was measured growing like 1 / distance (`text` gives the numbers);
//  unknown - neither proved.
struct PhiLipschitz {
  enum Kind { proved, fails, unknown } kind = unknown;
  std::string text;  // what was proved, or the failing entry, where and by how much
};
// z: the form's coordinates, phi in them; z_of_x empty when z are the states themselves.
PhiLipschitz phi_lipschitz_on_box(const Model& m, const std::vector<GiNaC::symbol>& z,
                                  const ExVec& phi, const ExVec& z_of_x);

struct PersistenceOptions {
  std::string input_text;  // comma-separated expressions in t, one per input
  double horizon = 20;
  double t0 = -1;  // start of the checked interval; < 0: horizon / 2
  std::vector<double> thetas = {1, 2, 5, 10, 20, 50};
  // p > 1 outside x: the observability indices (Observability::indices) giving the blocks.
  std::vector<std::size_t> indices;
};

struct PersistenceAtTheta {
  double theta = 0;
  bool gamma_invertible = true;  // min over t of min_i Gamma_ii / max_i Gamma_ii > 1e-13
  bool psi_positive = true;      // Psi positive definite at every checked t
  double alpha = 0;              // sup_t lambda_max(Psi^-1/2 Gamma Psi^-1/2) (inf if not PD)
  double gamma = 0;              // sup_t max_{j <= i} Gamma_ii / Gamma_jj
  double min_psi_eig = 0;        // min_t lambda_min(Psi)
  double worst_t = 0;            // t where alpha is attained (or Psi first singular)
};

struct PersistenceResult {
  bool applicable = false;
  std::string reason;  // why not applicable, or the form used
  std::string input_text;
  double horizon = 0, t0 = 0, window = 0;
  std::vector<PersistenceAtTheta> by_theta;
  double gramian_min_eig = 0;         // lambda_min G(u, 0, horizon)
  double window_gramian_min_eig = 0;  // min over windows [t - window, t], t in [t0, horizon]
  bool condition_i = false, condition_ii = false;
  bool persistent = false;
  PhiLipschitz lipschitz;  // the Theorem's other hypothesis, whatever the input
  std::string verdict;     // one sentence, says "sampled"
};

PersistenceResult check_persistence(const Model& m, const PersistenceOptions& opt);

nlohmann::ordered_json persistence_json(const PersistenceResult& r);
// format: "text", "markdown" or "latex".
std::string render_persistence(const PersistenceResult& r, const std::string& format);

}  // namespace obsynth
