// Where the model is defined on its domain box (issue 20). Every operation of f + g and h that
// restricts its argument gives a condition: a divisor != 0, the base of a non-integer power
// >= 0 (> 0 when the power is negative), the argument of log > 0, cos of tan's argument != 0,
// |arg| <= 1 for asin / acos. Each is decided on the box in Arb balls with bisection: proved
// everywhere, violated on the whole box, violated on a sub-box (proved by a point or a sign
// change, or only not excluded), and the sub-box where it fails is reported. Magnitudes are
// checked too: a value of f, g or h beyond 1e150 on the box, or a model coefficient outside
// [1e-150, 1e150], leaves double precision no headroom (certificates square them).
#pragma once

#include <string>
#include <vector>

#include "foundation/diagnostics.hpp"
#include "front/model.hpp"

namespace obsynth::certify {

// Largest magnitude obsynth accepts for a value of the model on its box, and the range of its
// nonzero coefficients: squares (Riccati, Lipschitz products, norms) must stay finite.
inline constexpr double kMagnitudeLimit = 1e150;

enum class DefinedStatus {
  violated_everywhere,  // proved: the condition fails at every point of the box
  violated_somewhere,   // proved: it fails at a point (or on a sub-box) of the box
  not_excluded,         // the enclosure could not exclude a failure inside `sub_box`
};

struct DefinednessFinding {
  std::string component;    // "f2", "h1"
  std::string expression;   // the component, printed
  std::string requirement;  // "x1 != 0 (a denominator)", "x1 >= 0 (sqrt's argument)", ...
  DefinedStatus status = DefinedStatus::not_excluded;
  std::string sub_box;             // where it fails or may fail, e.g. "x1 in [-0.0039, 0.0039]"
  std::string witness;             // how a failure was proved, e.g. "x1 = 0 gives exactly 0"
  SourceLoc loc;                   // of the component in the model file
  std::string text() const;        // one clause: component, requirement, where, witness
  std::string short_text() const;  // component, requirement and sub-box only
};

struct Definedness {
  std::size_t conditions = 0;                // conditions checked
  std::vector<DefinednessFinding> findings;  // every condition not proved on the whole box
  std::vector<Diagnostic> magnitude_errors;  // values or coefficients beyond kMagnitudeLimit

  // A failure is proved somewhere in the box (designs exclude themselves).
  bool undefined_somewhere() const;
  // Some condition is proved violated on the whole box, or a magnitude is out of range:
  // the model cannot be used at all (the analysis ends with these diagnostics).
  std::vector<Diagnostic> errors() const;
  // One sentence for reports: "defined on the domain box (N conditions proved)" or the findings.
  std::string summary() const;
};

// The conditions and magnitudes of the model's f + g and h on Model::box().
Definedness check_definedness(const Model& m);

}  // namespace obsynth::certify
