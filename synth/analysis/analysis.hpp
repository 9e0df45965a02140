// The analysis pipeline: model -> Lie derivatives -> observability -> canonical form.
#pragma once

#include <map>
#include <string>

#include "analysis/budget.hpp"
#include "analysis/canonical.hpp"
#include "analysis/observability.hpp"
#include "front/model.hpp"

namespace obsynth {

struct AnalysisOptions {
  BudgetLimits budget;
  Budget::StageListener on_stage;  // e.g. the worker's publish_stage
  ObservabilityOptions observability;
  CanonicalOptions canonical;
};

struct Analysis {
  Model model;
  Observability observability;
  CanonicalForm canonical;
  std::map<std::string, double> timings_ms;
};

Analysis analyse(const Model& m, const AnalysisOptions& opt = {});

}  // namespace obsynth
