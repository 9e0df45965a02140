#include "analysis/analysis.hpp"

namespace obsynth {

Analysis analyse(const Model& m, const AnalysisOptions& opt) {
  Budget budget(opt.budget, opt.on_stage);
  Analysis a;
  a.model = m;
  a.observability = analyse_observability(m, budget, opt.observability);
  if (a.observability.jets)  // no symbolic Lie derivatives: nothing for r, the frame, T
    a.canonical.not_applicable = "skipped: " + a.observability.symbolic_skipped +
                                 "; r, the frame, the brackets, T and l need them";
  else
    a.canonical = analyse_canonical(m, a.observability, budget, opt.canonical);
  budget.end();
  a.timings_ms = budget.timings_ms();
  return a;
}

}  // namespace obsynth
