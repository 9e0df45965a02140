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
  std::optional<GiNaC::ex> psi;  // psi(y) in the measurement symbol y (cf.y[0])
  GiNaC::ex c = 0;               // phi'/phi = c(y), when found
  std::string how;               // which bracket fixed c, or why there is no candidate
};

// One output, the canonical form applicable and its bracket conditions failing: the candidate
// psi, or why there is none (a bracket free of the jets that fails whatever psi, c not a
// function of y, an integral outside the integrator's class).
OutputTransformationCandidate output_transformation_candidate(const Model& m,
                                                              const CanonicalForm& cf);

// The model observed through psi: h replaced by psi(h), simplified.
Model transformed_output(const Model& m, const GiNaC::ex& psi, const GiNaC::symbol& y);

}  // namespace obsynth
