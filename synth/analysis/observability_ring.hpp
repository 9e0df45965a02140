// A cheaper observability analysis for stages that need only the rank and det O, not the Lie
// derivatives as expressions (observability under inputs).
#pragma once

#include <optional>

#include "analysis/observability.hpp"
#include "analysis/triangular_form.hpp"
#include "foundation/budget.hpp"
#include "front/model.hpp"

namespace obsynth {

// analyse_observability's generic_rank, rows, selected, indices, det, rank_drop and jets,
// without `lie` (empty) when the Lie chain lives in the polynomial ring. O is empty too when it
// is triangular (one output): its diagonal alone, converted to GiNaC, decides rank and det.
Observability observability_rank(const Model& m, Budget& budget,
                                 const ObservabilityOptions& opt = {});

// The same for a model in seed 002's triangular form (y = z1, a_i(u) free of x, phi triangular)
// with its inputs frozen, without a Lie chain: in z, row k of O_u is triangular with diagonal
// a_1(u) ... a_k(u), and O_u = O_u^z dz/dx. So
//  - z a permutation of x (states): det O_u = sign(order) prod_k a_1 ... a_k;
//  - z = (h, L_f h, ...) (lie_derivatives): a_i = 1 and dz/dx is the drift's O, so O_u has the
//    drift's rank, det and rank-drop set (no input makes it drop).
// `frozen` is the model with frozen inputs (its boxes decide the zero tests), `drift` the
// model's own analysis; nullopt when a diagonal entry vanishes identically or the drift's det
// is not available.
std::optional<Observability> observability_of_triangular_form(const Model& frozen,
                                                              const TriangularForm& t,
                                                              const Observability& drift);

}  // namespace obsynth
