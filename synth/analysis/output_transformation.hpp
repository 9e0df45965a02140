// Linearization by output injection after an output transformation y~ = psi(y) (Krener and
// Respondek 1985; one output). With y~ = psi(h) the dual field is r~ = phi(h) r, phi = 1 / psi',
// since L_r L_f^k psi(h) = 0 for k < n - 1 and psi'(h) for k = n - 1. The frame tau~_1 = r~,
// tau~_{k+1} = [-f, tau~_k] is linear in the jets P_j = phi^(j)(h) (chain rule), so each bracket
// [tau~_i, tau~_j] is a quadratic form in them; with phi = exp(Phi), P_j = P_0 q_j and q_1 =
// Phi'(h) = c. The first bracket that involves the q at all fixes c when it is linear in q_1
// alone; c must then be a function of y, and psi = integral of exp(-integral of c). The caller
// verifies the candidate by analysing the model with h replaced by psi(h) from scratch.
#pragma once

#include <ginac/ginac.h>

#include <optional>
#include <string>

#include "analysis/canonical.hpp"
#include "front/model.hpp"

namespace obsynth {

struct OutputTransformationCandidate {
  std::optional<ExVec> psi;  // psi_i(y_i) in the measurement symbols (cf.y), one per output
  GiNaC::ex c = 0;           // one output: phi'/phi = c(y), when found
  std::string how;           // how the candidate was found, or why there is none
};

// The canonical form applicable and its bracket conditions failing: the candidate psi, or why
// there is none. One output: the jets construction above (a bracket free of the jets that fails
// whatever psi, c not a function of y, an integral outside the integrator's class). Several
// outputs: each output that reads a single state through an invertible map, y_i = s_i(x_k), is
// inverted, psi_i = s_i^-1 (the sensor's own nonlinearity); the others are kept.
OutputTransformationCandidate output_transformation_candidate(const Model& m,
                                                              const CanonicalForm& cf);

// The model observed through psi: h_i replaced by psi_i(h_i), simplified.
Model transformed_output(const Model& m, const ExVec& psi, const std::vector<GiNaC::symbol>& y);

}  // namespace obsynth
