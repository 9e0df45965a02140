// The generated perfect observer of seed 003's example (generated/slawinski17_perfect.hpp):
// reconstructs the state up to the differentiator's documented error
// (runtime/obsynth/differentiator.hpp: |e_1| <= C(2,1) epsilon M_2 for K = 1), with zero
// allocations per step, under the contract flags.
#include "slawinski17_perfect.hpp"

#include <cmath>
#include <cstdio>

#include "alloc_counter.hpp"

namespace gen = obsynth_gen::slawinski17;
using Obs = gen::Slawinski17Perfect<double>;
using F = gen::PerfectFunctions<double>;
static_assert(obsynth::is_observer_v<Obs>, "observer interface");
static_assert(obsynth::is_observer_v<gen::Slawinski17Perfect<float>>, "observer interface (float)");

namespace {

int passed = 0, failed = 0;
void expect(bool ok, const char* what, double got, double bound) {
  if (ok) {
    ++passed;
  } else {
    ++failed;
    std::printf("FAIL: %s (got %.6g, bound %.6g)\n", what, got, bound);
  }
}

double input(double t) {
  return 0.5 * std::sin(t);
}

F::State field(const F::State& x, double u) {
  F::State a, b;
  F::Input uu;
  uu(0) = u;
  F::f(x, a);
  F::g(x, uu, b);
  return a + b;
}

}  // namespace

int main() {
  // Reconstruction from exact jets is exact: xh = [y, -y' + (1 + y) u] (seed 003, eq. 29).
  {
    F::YJet yj;
    F::UJet uj;
    yj << 0.7, -0.4;
    uj << 0.3;
    F::State x;
    F::reconstruct(yj, uj, x);
    expect(std::fabs(x(0) - 0.7) < 1e-15, "reconstruct x1 = y", x(0), 0.7);
    expect(std::fabs(x(1) - (0.4 + 1.7 * 0.3)) < 1e-15, "reconstruct x2 = -y' + (1 + y) u", x(1),
           0.4 + 1.7 * 0.3);
  }
  const double eps = 1e-3, dt = 1e-4, t_end = 5;
  Obs obs(eps);
  F::State x;
  x << 0.5, -0.3;
  obs.reset(F::State::Zero());
  double max_ydd = 0, max_err_tail = 0, yd_prev = 0;
  std::size_t allocations = 0;
  obsynth::test::AllocationCounter counter;
  const int steps = static_cast<int>(t_end / dt + 0.5);
  for (int k = 0; k < steps; ++k) {
    const double t = k * dt;
    // plant, RK4 with the exact input
    const F::State k1 = field(x, input(t)), k2 = field(x + dt / 2 * k1, input(t + dt / 2)),
                   k3 = field(x + dt / 2 * k2, input(t + dt / 2)),
                   k4 = field(x + dt * k3, input(t + dt));
    x += dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
    const double t1 = t + dt;
    F::Input u;
    u(0) = input(t1);
    F::Output y;
    y(0) = x(0);
    counter.restart();
    obs.step(dt, u, y);
    allocations += counter.allocations();
    const double yd = field(x, input(t1))(0);  // y' = x1'
    if (k > 0) max_ydd = std::fmax(max_ydd, std::fabs(yd - yd_prev) / dt);
    yd_prev = yd;
    if (t1 > 1.0)
      max_err_tail = std::fmax(max_err_tail, (x - obs.estimate()).cwiseAbs().maxCoeff());
  }
  // x2 = -y' + (1 + y) u: its error is the y' error plus (1 + |u|) times the (much smaller)
  // y error; the documented bias bound of y' is 2 epsilon M_2. 20% margin for the sampled M_2.
  const double bound = 1.2 * (2 * eps * max_ydd) * (1 + 0.5 * eps);
  expect(obs.status() == obsynth::Status::ok, "status ok", 0, 0);
  expect(max_err_tail <= bound, "error after the start-up transient within the documented bound",
         max_err_tail, bound);
  expect(max_err_tail > 0.05 * bound, "the bound is not vacuous (error is of its order)",
         max_err_tail, 0.05 * bound);
  expect(allocations == 0, "zero allocations per step", static_cast<double>(allocations), 0);
  std::printf(
      "perfect observer: max error for t > 1: %.3e, documented bound %.3e (epsilon %g, M2 %.3g)\n",
      max_err_tail, bound, eps, max_ydd);
  std::printf("perfect_slawinski17: %d passed, %d failed\n", passed, failed);
  return failed == 0 ? 0 : 1;
}
