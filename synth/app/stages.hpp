// The stages a design runs under in the main job, and what the main job does after a budget
// stops one of them (the retry policy): skip the canonical-form stages, pass over the design
// auto chose, or end the run.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "app/synthesize.hpp"

namespace obsynth {

// A design's own stages, each under its own budget stage name "<method> <stage>".
enum class DesignStage {
  verdict,  // its verdict and certificate (auto's ranking)
  design,   // its build
  trial,    // auto's closed-loop trial
};

// "<method> verdict", "<method> design", "<method> trial".
std::string design_stage_name(const std::string& method, DesignStage stage);

struct StoppedDesignStage {
  std::string method;
  DesignStage stage;
};
// The design and stage of a stage name, or nothing for an analysis stage.
std::optional<StoppedDesignStage> parse_design_stage(const std::string& stage_name);

// Why auto passes over a design whose stage stopped: "its verdict stopped: ", ...
std::string passed_over_clause(DesignStage stage);
// Whether an exclusion's reason says its verdict stopped (the report then says "not evaluated").
bool verdict_stopped(const ExcludedDesign& e);

// The retry policy after a budget stop in a worker (time or memory): what the main job does.
struct RetryState {
  std::string canonical_skipped;  // why the canonical-form stages are skipped ("" = not)
  std::vector<ExcludedDesign> excluded;
};
enum class AfterStop {
  rerun,  // state updated: run again
  end,    // print the checkpoint and the diagnostic, exit 1
};
// `methods`: the --method list; `stage`, `reason`: the stop. Auto and all may drop the
// canonical-form stages (once); auto passes over the design whose stage stopped.
AfterStop after_stop(const std::vector<std::string>& methods, const std::string& stage,
                     const std::string& reason, RetryState& state);

// auto and all may pick a design that does not need the canonical form (the stages after the
// observability rank): a budget stop in those stages then skips them instead of ending the job.
bool may_skip_canonical_form(const std::vector<std::string>& methods);

}  // namespace obsynth
