// One closed-loop run of a design through obsynth simulate's engine (continuous sampling,
// dt = 1e-3), for design tests that judge convergence on the simulated error.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "analysis/analysis.hpp"
#include "app/simulate.hpp"
#include "designs/options.hpp"
#include "front/model.hpp"

namespace obsynth::testing {

inline SimulationResult run(const Model& m, const std::string& method, const std::string& u,
                            std::vector<double> x0, std::vector<double> xh0, double t_end,
                            DesignOptions d = {}) {
  SimulationOptions o;
  o.method = method;
  o.design = std::move(d);
  o.u_text = u;
  o.x0 = std::move(x0);
  o.xhat0 = std::move(xh0);
  o.t_end = t_end;
  o.dt = 1e-3;
  return simulate(analyse(m), o);
}

}  // namespace obsynth::testing
