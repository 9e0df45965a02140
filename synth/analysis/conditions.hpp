// The conditions stage of the canonical form (seed 003 Lemma 1): C2 [tau_i, tau_j] = 0,
// C3 [g, tau_j] = 0 with u a constant symbol, C4 completeness of every tau_k.
#pragma once

#include <string>

#include "analysis/budget.hpp"
#include "analysis/canonical.hpp"
#include "analysis/frame.hpp"
#include "front/model.hpp"

namespace obsynth {

// Fills cf.drift, cf.input, cf.linearizable, cf.complete and cf.complete_reason; appends g to
// the ring's fields when the frame lives in the ring.
void check_conditions(const Model& m, FrameRing& fr, Budget& budget, const CanonicalOptions& opt,
                      CanonicalForm& cf);

}  // namespace obsynth
