#include "analysis/analysis.hpp"

namespace obsynth {

Analysis analyse(const Model& m, const AnalysisOptions& opt) {
  Budget budget(opt.budget, opt.on_stage);
  Analysis a;
  a.model = m;
  a.observability = analyse_observability(m, budget, opt.observability);
  a.canonical = analyse_canonical(m, a.observability, budget, opt.canonical);
  budget.end();
  a.timings_ms = budget.timings_ms();
  return a;
}

}  // namespace obsynth
