// SPDX-License-Identifier: MIT
// Copyright (c) obsynth authors
//
// seed003_firmware: runs the observer that obsynth generates at build time from plant.sym
// (CMakeLists.txt: obsynth_add_observer(app MODEL plant.sym METHOD canonical PRECISION float))
// against a simulated plant, the way firmware would: once per sample it reads y, applies u and
// calls step().
//
// Plant (seed 003, eq. 17):  x1' = -x2 + (1 + x1) u,  x2' = -x1 x2 + u,  y = x1,  u = sin(t).
// It is simulated in double with a hand-written RK4 (u = sin(t) evaluated at every stage), from
// x(0) = (0.5, -0.3); the observer runs in float from the wrong estimate xh(0) = (0, 0).
//
// The error z - zh of the canonical observer decays with its poles (-2, -2.5), so after 10 s
// the initial error has shrunk by e^{-20}; what is left is the sampling floor: the observer
// holds u and y over a step while the plant's move, an O(dt) effect (a few 1e-4 at dt = 1e-4
// on this trajectory) plus float rounding.
//
// Prints |x - xh|_inf every second; exit status 0 only if every step returned Status::ok and
// the final error is below 1e-3.
#include <cmath>
#include <cstdio>

#include "obsynth/observer.hpp"
#include "slawinski17_canonical.hpp"

namespace {

using Observer = obsynth_gen::slawinski17::Slawinski17Canonical<float>;
static_assert(obsynth::is_observer_v<Observer>, "generated observer must meet the runtime interface");

struct PlantState {
  double x1, x2;
};

double input(double t) { return std::sin(t); }

PlantState plant_rhs(const PlantState& x, double u) {
  return {-x.x2 + (1.0 + x.x1) * u, -x.x1 * x.x2 + u};
}

PlantState axpy(const PlantState& x, double a, const PlantState& k) {
  return {x.x1 + a * k.x1, x.x2 + a * k.x2};
}

// One classical RK4 step of the plant from t to t + dt, with u = sin(t) at every stage.
PlantState plant_rk4(const PlantState& x, double t, double dt) {
  const PlantState k1 = plant_rhs(x, input(t));
  const PlantState k2 = plant_rhs(axpy(x, dt / 2, k1), input(t + dt / 2));
  const PlantState k3 = plant_rhs(axpy(x, dt / 2, k2), input(t + dt / 2));
  const PlantState k4 = plant_rhs(axpy(x, dt, k3), input(t + dt));
  return {x.x1 + dt / 6 * (k1.x1 + 2 * k2.x1 + 2 * k3.x1 + k4.x1),
          x.x2 + dt / 6 * (k1.x2 + 2 * k2.x2 + 2 * k3.x2 + k4.x2)};
}

double estimate_error(const PlantState& x, const Observer& obs) {
  const Observer::State& xh = obs.estimate();
  return std::fmax(std::fabs(x.x1 - static_cast<double>(xh(obsynth_gen::slawinski17::state::x1))),
                   std::fabs(x.x2 - static_cast<double>(xh(obsynth_gen::slawinski17::state::x2))));
}

}  // namespace

int main() {
  constexpr double dt = 1e-4;            // sample period [s]
  constexpr long steps_per_second = 10000;
  constexpr long seconds = 10;
  constexpr double tolerance = 1e-3;

  PlantState x{0.5, -0.3};
  Observer obs;
  obs.reset(Observer::State(0.0f, 0.0f));  // wrong on purpose

  std::printf("seed003_firmware: %s observer, float, dt = %g s\n", "Slawinski17Canonical", dt);
  std::printf("%6s %12s %12s %12s %12s %12s\n", "t", "x1", "x2", "xh1", "xh2", "|x - xh|");
  const auto print = [&](double t) {
    const Observer::State& xh = obs.estimate();
    std::printf("%6.1f %12.6f %12.6f %12.6f %12.6f %12.3e\n", t, x.x1, x.x2, static_cast<double>(xh(0)),
                static_cast<double>(xh(1)), estimate_error(x, obs));
  };
  print(0.0);

  bool all_ok = true;
  for (long k = 0; k < seconds * steps_per_second; ++k) {
    const double t = static_cast<double>(k) * dt;
    // Sample: the input applied now and the measurement y = x1.
    Observer::Input u;
    u(obsynth_gen::slawinski17::input::u) = static_cast<float>(input(t));
    Observer::Output y;
    y(0) = static_cast<float>(x.x1);
    const obsynth::Status s = obs.step(static_cast<float>(dt), u, y);
    if (s != obsynth::Status::ok) {
      std::printf("step at t = %g returned %s\n", t, obsynth::status_name(s));
      all_ok = false;
      break;
    }
    x = plant_rk4(x, t, dt);
    if ((k + 1) % steps_per_second == 0) print(static_cast<double>(k + 1) * dt);
  }

  const double final_error = estimate_error(x, obs);
  const bool converged = all_ok && final_error < tolerance;
  std::printf("final error %.3e (tolerance %.0e): %s\n", final_error, tolerance,
              converged ? "converged" : "NOT converged");
  return converged ? 0 : 1;
}
