// The analysis pipeline: model -> Lie derivatives -> observability -> canonical form.
#pragma once

#include <map>
#include <string>

#include "budget.hpp"
#include "canonical.hpp"
#include "model.hpp"
#include "observability.hpp"

namespace obsynth {

struct AnalysisOptions {
  BudgetLimits budget;
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
