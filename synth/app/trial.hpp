// auto's closed-loop trial: the observer it chose, built, run against the plant in the
// simulator from initial errors of 20 % of the domain box. Sampled evidence, never a proof:
// it catches a chosen observer that rejects its first step, leaves the box or diverges, so
// that auto passes over it to the next design. The certificates still rank the designs.
#pragma once

#include <string>

#include "analysis/analysis.hpp"
#include "designs/spec.hpp"

namespace obsynth {

enum class TrialVerdict {
  passed,        // every run converged: final error below 2 % of the box and e(0) / 10
  slow,          // every run's error fell, but not that far within the horizon
  failed,        // a run rejected its step, left the finite numbers or the box, or grew
  inconclusive,  // the plant itself left the box: the trial says nothing about the observer
};

struct TrialOutcome {
  TrialVerdict verdict = TrialVerdict::inconclusive;
  std::string setup;  // how it was run: inputs, horizon, step, runs
  std::string text;   // what it found, one clause
};

// The trial's set-up is the model's own: x0 inside the box (45 % of each width), xhat0 moved
// by 20 % of each width (alternating signs, then mirrored: two runs), each input at its box
// centre plus a quarter-width sine at the model's time scale (inputs without a box: u0),
// a horizon of 300 time constants 1 / rho (rho the largest |eigenvalue| of df/dx over a few
// box points), and RK4 steps of 0.02 / rho (a run that leaves the finite numbers is run once
// more with steps ten times shorter).
TrialOutcome closed_loop_trial(const Analysis& a, const ObserverSpec& spec);

}  // namespace obsynth
