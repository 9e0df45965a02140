// `obsynth simulate`: plant and observer side by side, the observer evaluated through the
// same expression DAGs that the emitted C++ is printed from.
#pragma once

#include <string>
#include <vector>

#include "analysis/analysis.hpp"
#include "designs/observers.hpp"

namespace obsynth {

enum class Sampling {
  continuous,  // plant and observer integrated as one ODE (y, u exact at RK4 stages)
  zoh,         // the firmware step(): u, y sampled at t_k and held over the step
};

struct SimulationOptions {
  std::string method = "canonical";
  CanonicalDesignOptions canonical;
  std::string u_text = "0";  // comma-separated expressions in t, one per input
  std::vector<double> x0, xhat0;
  double t_end = 10, dt = 1e-3;
  Sampling sampling = Sampling::continuous;
  double epsilon = 0.01;  // perfect observer: differentiator time constant
  int newton_iterations = 8;
  double newton_tolerance = 1e-13;
};

struct SimulationResult {
  std::vector<std::string> names;
  std::vector<double> t;
  std::vector<std::vector<double>> x, xh;
  std::string csv;
  std::string svg;
  std::string summary;
};

SimulationResult simulate(const Analysis& a, const SimulationOptions& opt);

}  // namespace obsynth
