// The analysis pipeline: model -> Lie derivatives -> observability -> canonical form.
// Stages: lie, observability, frame, conditions, diffeomorphism. A budget stop (time,
// expression size, memory) ends the pipeline but keeps the results of the stages that
// completed; Analysis::stages says which did.
#pragma once

#include <functional>
#include <map>
#include <string>
#include <vector>

#include "analysis/canonical.hpp"
#include "analysis/observability.hpp"
#include "analysis/observability_inputs.hpp"
#include "certify/definedness.hpp"
#include "foundation/budget.hpp"
#include "front/model.hpp"

namespace obsynth {

// completed: its results are in the Analysis. stopped: a budget ended it; its results and
// those of every later stage are absent. not run: after a stopped stage. not needed: the
// analysis ended before it (not observable, brackets fail).
enum class StageStatus { completed, stopped, not_run, not_needed };
const char* stage_status_name(StageStatus s);  // "completed", "stopped", "not run", "not needed"

struct StageOutcome {
  std::string name;
  StageStatus status = StageStatus::not_run;
  std::string reason;  // why it stopped, did not run, or was not needed; empty when completed
};

struct Analysis;

struct AnalysisOptions {
  BudgetLimits budget;
  Budget::StageListener on_stage;  // e.g. the worker's publish_stage
  ObservabilityOptions observability;
  CanonicalOptions canonical;
  // false: a budget stop throws BudgetExceeded (callers that need every stage, e.g. the main
  // job). true: analyse returns the results of the completed stages, complete() false.
  bool keep_partial = false;
  // false: skip the canonical-form stages (frame, conditions, diffeomorphism: reported "not
  // needed"), for designs that need only the model and the observability rank.
  bool canonical_form = true;
  // Why the canonical form was skipped, when canonical_form is false (default: the methods asked
  // for do not need it).
  std::string canonical_skipped = "the methods asked for do not need the canonical form";
  // Called as each stage begins with the results of the stages before it, the beginning stage
  // marked stopped with checkpoint_reason: what to report should the process die in it.
  std::function<void(const Analysis&)> on_checkpoint;
  std::string checkpoint_reason = "stopped";
};

struct Analysis {
  Model model;
  // Where f + g and h are defined on the domain box (poles, roots and logs of negatives,
  // magnitudes), decided before any stage: a model undefined on its whole box, or with values
  // beyond double's headroom, ends analyse() with a UserError.
  certify::Definedness definedness;
  Observability observability;
  // Observability with the inputs as constant symbols, uniform observability (issue 8);
  // computed right after the drift observability, under its own budget.
  ObservabilityUnderInputs under_inputs;
  CanonicalForm canonical;
  // Bracket conditions that fail for y = h(x) but hold for y~ = psi(y)
  // (analysis/output_transformation.hpp): `canonical` is then the form of `model` with h replaced
  // by psi(h) (`observed`), and the designs that take it observe psi(y). Searched only when the
  // conditions fail; `output_transformation_note` says what the search found or why none.
  struct OutputTransformation {
    ExVec psi;                     // psi_i(y_i), one per output (y_i itself when unchanged)
    std::vector<GiNaC::symbol> y;  // the measurement symbols of the form
    Model observed;                // the model with h_i = psi_i(h_i)
    std::string how;               // how psi was found and verified
    std::string failing;           // the conditions that fail for y itself, by name
    // Those conditions with their residuals and witness points, as for y itself.
    std::vector<std::pair<std::string, BracketCheck>> failing_checks;
  };
  std::optional<OutputTransformation> output_transformation;
  std::string output_transformation_note;
  // The model the canonical form belongs to: `observed` after an output transformation.
  const Model& canonical_model() const {
    return output_transformation ? output_transformation->observed : model;
  }
  std::map<std::string, double> timings_ms;
  std::vector<StageOutcome> stages;  // every stage of the pipeline, in order

  // No stage was stopped (stages that were not needed do not count).
  bool complete() const;
  // The stopped stage, or nullptr.
  const StageOutcome* stopped_stage() const;
  // Whether the stage's results are present. True for a stage not listed in `stages`.
  bool completed(const std::string& stage) const;
  // Whether the stage's results were lost to a stop (stopped or not run).
  bool lost(const std::string& stage) const;
};

// The stages in pipeline order.
const std::vector<std::string>& pipeline_stages();

Analysis analyse(const Model& m, const AnalysisOptions& opt = {});

}  // namespace obsynth
