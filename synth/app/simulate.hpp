// `obsynth simulate`: plant and observer side by side. The observer is the design's
// ObserverSpec, evaluated through the same expression DAGs that the emitted code is printed
// from; the plant is the model's field.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "analysis/analysis.hpp"
#include "designs/spec.hpp"

namespace obsynth {

enum class Sampling {
  continuous,  // plant and observer integrated as one ODE (y, u exact at RK4 stages)
  zoh,         // the firmware step(): u, y sampled at t_k and held over the step
};

struct SimulationOptions {
  std::string method = "canonical";
  DesignOptions design;
  std::string u_text = "0";  // comma-separated expressions in t, one per input
  std::vector<double> x0, xhat0;
  double t_end = 10, dt = 1e-3;
  Sampling sampling = Sampling::continuous;
  double newton_tolerance = 1e-13;
  // Values the plant takes for free parameters, "name=value" (--plant-param, repeatable); the
  // observer keeps its own (the --param binding or its run-time default, the box centre).
  std::vector<std::string> plant_params;
  // The model as read, before the --param bindings (null: the analysis's model): lets the
  // plant differ from the observer in a parameter that --param bound for the observer.
  const Model* unbound_model = nullptr;
};

struct SimulationResult {
  std::string method;       // the design that ran (auto resolved)
  std::string explanation;  // why auto chose it; empty when the method was named
  std::vector<std::string> names;
  std::vector<double> t;
  std::vector<std::vector<double>> x, xh;
  std::string csv;
  std::string svg;
  std::string summary;
  // Set when the plant or the observer left the finite numbers: the run stopped there and
  // the CSV and plot end at the last finite sample.
  std::string diverged;
};

SimulationResult simulate(const Analysis& a, const SimulationOptions& opt);

// The largest RK4 step of an ODE observer (UpdateKind::ode, no solve or symmetric blocks: the
// designs with those report their own) that keeps its own dynamics stable, sampled: the RK4
// stability radius 2.785 over the largest |eigenvalue| of d(rhs)/dw at 64 Halton points of the
// domain box (w = init(x), y = h(x, u): the estimate on the trajectory). nullopt otherwise.
constexpr double kRk4StabilityRadius = 2.785;
struct SafePeriod {
  double period = 0, rho = 0;
  std::size_t samples = 0;
};
std::optional<SafePeriod> sampled_safe_period(const Analysis& a, const ObserverSpec& spec);

// Plant and an observer already built: the trajectories only (no CSV, no plot; opt.method and
// opt.design unused). A run that leaves the finite numbers or rejects a step ends there, with
// `diverged` set. plant_note, when given, receives the --plant-param line.
SimulationResult run_closed_loop(const Analysis& a, const ObserverSpec& spec,
                                 const SimulationOptions& opt, std::string* plant_note);

}  // namespace obsynth
