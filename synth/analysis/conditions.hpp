// The conditions stage of the canonical form (seed 003 Lemma 1): C2 [tau_i, tau_j] = 0,
// C3 [g, tau_j] = 0 with u a constant symbol, C4 completeness of every tau_k.
#pragma once

#include <string>
#include <vector>

#include "analysis/canonical.hpp"
#include "analysis/frame.hpp"
#include "foundation/budget.hpp"
#include "front/model.hpp"

namespace obsynth {

// Fills cf.drift, cf.input, cf.output, cf.linearizable, cf.complete and cf.complete_reason; appends
// g to the ring's fields when the frame lives in the ring.
void check_conditions(const Model& m, FrameRing& fr, Budget& budget, const CanonicalOptions& opt,
                      CanonicalForm& cf);

// "[tau_1, tau_2] = 0", "[g, tau_{2,1}] = 0", "<dh_1, tau_{2,1}> = 0": a condition's name.
std::string drift_condition_name(const CanonicalForm& cf, const BracketCheck& b);
std::string input_condition_name(const CanonicalForm& cf, const BracketCheck& b);
std::string output_condition_name(const CanonicalForm& cf, const BracketCheck& b);

// C2, C3 (and C5) all proved: only then is the model proved linearizable (cf.linearizable also
// admits brackets that are only numerically zero).
bool conditions_proved(const CanonicalForm& cf);

// What the canonical form rests on without a proof: the brackets and the checks of T, T^-1 and
// l(u, y) whose verdict is only numeric, e.g. "[tau_1, tau_2] = 0 (numerically zero at 31
// points)". Empty when everything computed is proved.
std::vector<std::string> unproven_steps(const CanonicalForm& cf);

// A bracket's verdict for reports: "holds (proved)", "unproven (numerically zero at N points)",
// "FAILS (nonzero)".
std::string bracket_verdict_text(const BracketCheck& b);

// The witness of a failing bracket in the model's symbol order, e.g. "w = 0.00494, cur = 3.1";
// empty when there is none.
std::string witness_text(const Model& m, const BracketCheck& b);

}  // namespace obsynth
