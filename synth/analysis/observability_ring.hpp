// A cheaper observability analysis for stages that need only the rank and det O, not the Lie
// derivatives as expressions (observability under inputs).
#pragma once

#include <optional>

#include "analysis/budget.hpp"
#include "analysis/observability.hpp"
#include "analysis/triangular_form.hpp"
#include "front/model.hpp"

namespace obsynth {

// analyse_observability's generic_rank, rows, selected, indices, det, rank_drop and jets,
// without `lie` (empty) when the Lie chain lives in the polynomial ring. O is empty too when it
// is triangular (one output): its diagonal alone, converted to GiNaC, decides rank and det.
Observability observability_rank(const Model& m, Budget& budget,
                                 const ObservabilityOptions& opt = {});

// The same for a model in seed 002's triangular form in the states (z a permutation of x, y =
// z1, a_i(u) free of x) with its inputs frozen: in z, row k of O_u is triangular with diagonal
// a_1(u) ... a_k(u), so det O_u = sign(order) prod_k a_1 ... a_k with no Lie chain at all.
// `frozen` is the model with frozen inputs (its boxes decide the zero tests); nullopt when a
// diagonal entry vanishes identically or the form is in other coordinates.
std::optional<Observability> observability_of_triangular_form(const Model& frozen,
                                                              const TriangularForm& t);

}  // namespace obsynth
