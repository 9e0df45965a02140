// Observability under inputs (design.md §1, issue 8): the drift rank (u = 0) is what the
// canonical form needs, but a model such as seed 002's example (4) is unobservable only at
// u = 0. This stage decides
//  - the generic rank of O_u, the rows dL_{f+g(.,u)}^k h with the inputs as constant symbols
//    (sampled on the input box like free parameters), and the singular inputs: the x-free
//    factors of det O_u (of the selected rows when p > 1) that depend on the inputs, each with
//    whether it vanishes in the input box;
//  - when rank O_u < n, whether any input at all makes the model observable: the rank of the
//    observation space, the differentials of L_{X_k} ... L_{X_1} h for fields X = f + g(., v)
//    with independent input values v per step (words of length < n), at random points;
//  - uniform observability (seed 002: observable for every input) where the structure decides
//    it: the triangular form (triangular_form.hpp) with a_i(u) != 0 on the input box -> true;
//    an a_i, or a singular input factor, that vanishes at an admissible input -> false; no
//    input observable -> false; otherwise null (undecided), with the reason.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "analysis/observability.hpp"
#include "analysis/triangular_form.hpp"
#include "front/model.hpp"

namespace obsynth {

struct SingularInput {
  GiNaC::ex factor;  // expression in the inputs (and free parameters); its zeros are singular
  BoxZeros in_box;   // whether it vanishes on the input (and parameter) box
};

struct ObservabilityUnderInputs {
  bool computed = false;  // false: not computed (reason says why)
  std::size_t n = 0;
  std::size_t generic_rank = 0;
  std::string rank_method;       // as for the drift rank
  bool same_as_drift = false;    // no input enters f + g or h: O_u is the drift's O
  std::optional<GiNaC::ex> det;  // det O_u (selected rows), when symbolic and rank n
  // x-free, input-dependent factors of det O_u (p > 1: of the selected rows' minor only, so a
  // superset of the inputs where the rank drops; they then decide nothing)
  std::vector<SingularInput> singular;
  ExVec rank_drop;  // x-dependent factors of det O_u (may involve u)
  // Rank of the observation space when generic_rank < n (else equal to it), and whether some
  // input makes the model observable (nullopt: undecided).
  std::optional<std::size_t> observation_space_rank;
  std::optional<bool> observable_for_some_input;
  std::optional<bool> uniformly_observable;
  std::string reason;
  std::optional<TriangularForm> triangular;
  std::string triangular_note;  // why no triangular form was found
};

// The model as analysed with the inputs frozen: f := f + g, g := 0, every input a free
// parameter with its domain box (default [-2, 2]).
Model frozen_input_model(const Model& m);

// `drift` is the model's Observability (its O, det and Lie chain are reused when no input
// enters). The stage runs under its own budget with the given limits; a budget stop leaves
// computed false with the reason.
ObservabilityUnderInputs analyse_observability_under_inputs(const Model& m,
                                                            const Observability& drift,
                                                            const ObservabilityOptions& opt = {},
                                                            const BudgetLimits& limits = {});

}  // namespace obsynth
