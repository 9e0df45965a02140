// Shared by bench_observer.cpp, chain_benchmarks.cpp and count_steps.cpp: realistic, varying
// observer inputs, precomputed from a plant simulation, so that nothing a step() consumes is a
// compile-time constant.
//
// A SampleSet holds kSamples samples (t_k, dt_k, u_k, y_k, x_k) of the plant
//   x' = f(x) + g(x, u(t)),  y = h(x) + small deterministic "measurement noise",
// simulated in double with 8 RK4 sub-steps per sample under a continuous input u(t) (two
// incommensurate sines), with a jittered sample period dt_k = dt * (1 +- 10 %). The plant maps
// f, g, h are taken from a generated observer's function struct (Obs::F), so the same code
// serves every generated model. The observer then sees (dt_k, u_k, y_k) exactly as a periodic
// firmware task would (zero-order hold), cycling through the kSamples samples.
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace obsynth_bench {

constexpr std::size_t kSamples = 4096;  // power of two: index wraps with a mask
constexpr double kNominalDt = 0.01;

/// Deterministic pseudo-random numbers in [-0.5, 0.5) (64-bit LCG, high bits).
class Lcg {
 public:
  explicit Lcg(std::uint64_t seed) : s_(seed) {}
  double next() {
    s_ = s_ * 6364136223846793005ULL + 1442695040888963407ULL;
    return static_cast<double>(s_ >> 11) * 0x1.0p-53 - 0.5;
  }

 private:
  std::uint64_t s_;
};

/// Samples in double; convert with SampleArrays<Obs> for a given observer type.
struct SampleSet {
  int n = 0, m = 0;
  std::vector<double> dt;   // kSamples
  std::vector<double> u;    // kSamples * m
  std::vector<double> y;    // kSamples
  std::vector<double> x;    // kSamples * n (true state at t_k)
  std::vector<double> xh0;  // initial estimate (true x0 + offset)
  bool finite = true;       // plant stayed finite
  double max_abs_x = 0;     // largest |x_i| along the trajectory
};

/// Input signal: two incommensurate sines, amplitude `amp`.
inline double input_signal(double t, int j, double amp) {
  return amp * (0.7 * std::sin(1.1 * t + 0.9 * j) + 0.3 * std::sin(3.7 * t + 0.4 + 0.5 * j));
}

/// Simulates the plant of the generated observer type GenD (instantiated in double: uses
/// GenD::F::f, ::g, ::h) from x0 and samples it. x0 has GenD::n entries.
template <class GenD>
SampleSet simulate_plant(const std::vector<double>& x0, double u_amp, double noise,
                         std::uint64_t seed, double jitter = 0.1) {
  using F = typename GenD::F;
  using State = typename GenD::State;
  using Input = typename GenD::Input;
  using Output = typename GenD::Output;
  constexpr int n = GenD::n, m = GenD::m;
  SampleSet s;
  s.n = n;
  s.m = m;
  s.dt.resize(kSamples);
  s.u.resize(kSamples * m);
  s.y.resize(kSamples);
  s.x.resize(kSamples * n);
  Lcg rng(seed);
  State x;
  for (int i = 0; i < n; ++i) x(i) = x0[static_cast<std::size_t>(i)];
  auto rhs = [&](const State& xs, double t, State& dx) {
    Input u;
    for (int j = 0; j < m; ++j) u(j) = input_signal(t, j, u_amp);
    State fx, gx;
    F::f(xs, fx);
    F::g(xs, u, gx);
    dx = fx + gx;
  };
  double t = 0;
  for (std::size_t k = 0; k < kSamples; ++k) {
    const double dt = kNominalDt * (1.0 + 2 * jitter * rng.next());
    Output y;
    F::h(x, y);
    s.dt[k] = dt;
    s.y[k] = y(0) + noise * rng.next();
    for (int j = 0; j < m; ++j)
      s.u[k * m + static_cast<std::size_t>(j)] = input_signal(t, j, u_amp);
    for (int i = 0; i < n; ++i) {
      s.x[k * n + static_cast<std::size_t>(i)] = x(i);
      s.max_abs_x = std::fmax(s.max_abs_x, std::fabs(x(i)));
      if (!std::isfinite(x(i))) s.finite = false;
    }
    constexpr int kSub = 8;
    const double h = dt / kSub;
    for (int q = 0; q < kSub; ++q) {  // classical RK4 with the continuous input
      State k1, k2, k3, k4;
      rhs(x, t, k1);
      rhs(x + 0.5 * h * k1, t + 0.5 * h, k2);
      rhs(x + 0.5 * h * k2, t + 0.5 * h, k3);
      rhs(x + h * k3, t + h, k4);
      x += (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
      t += h;
    }
  }
  s.xh0.resize(static_cast<std::size_t>(n));  // initial estimate: 0.05 off in every component
  for (int i = 0; i < n; ++i)
    s.xh0[static_cast<std::size_t>(i)] = x0[static_cast<std::size_t>(i)] + 0.05;
  return s;
}

/// The samples converted to an observer's own Scalar/Input/Output types.
template <class Obs>
struct SampleArrays {
  using Scalar = typename Obs::Scalar;
  std::vector<Scalar> dt;
  std::vector<typename Obs::Input> u;
  std::vector<typename Obs::Output> y;
  typename Obs::State xh0;

  explicit SampleArrays(const SampleSet& s) : dt(kSamples), u(kSamples), y(kSamples) {
    for (std::size_t k = 0; k < kSamples; ++k) {
      dt[k] = static_cast<Scalar>(s.dt[k]);
      for (int j = 0; j < Obs::m; ++j)
        u[k](j) = static_cast<Scalar>(s.u[k * Obs::m + static_cast<std::size_t>(j)]);
      y[k](0) = static_cast<Scalar>(s.y[k]);
    }
    for (int i = 0; i < Obs::n; ++i)
      xh0(i) = static_cast<Scalar>(s.xh0[static_cast<std::size_t>(i)]);
  }
};

/// Samples of the seed 003 plant (slawinski17): x0 = (0.4, -0.3), |u| <= 0.25, which keeps x
/// inside the declared domain [-2, 2]^2 (x1 stays below 1.8).
template <class GenD>
const SampleSet& seed003_samples() {
  static const SampleSet s = simulate_plant<GenD>({0.4, -0.3}, 0.25, 1e-3, 3);
  return s;
}

/// The same plant sampled with a fixed period (no jitter): the firmware case, where an
/// observer that caches per-dt data (the generated exact discretisation, the expert's folded
/// RK4 matrices) computes it once.
template <class GenD>
const SampleSet& seed003_samples_fixed_dt() {
  static const SampleSet s = simulate_plant<GenD>({0.4, -0.3}, 0.25, 1e-3, 3, 0.0);
  return s;
}

/// Samples of a constructed chain plant: x0 = 0, |u| <= 0.5; the trajectory then stays inside
/// the declared domain [-1, 1]^n for n = 2..8 (a start away from the origin, e.g. 0.3 in every
/// component, leaves it for n >= 6: the constructed T^-1 amplifies by powers of the states).
template <class GenD>
const SampleSet& chain_samples() {
  static const SampleSet s =
      simulate_plant<GenD>(std::vector<double>(static_cast<std::size_t>(GenD::n), 0.0), 0.5, 1e-3,
                           17 + static_cast<std::uint64_t>(GenD::n));
  return s;
}

/// The same with a fixed sample period (the firmware case).
template <class GenD>
const SampleSet& chain_samples_fixed_dt() {
  static const SampleSet s =
      simulate_plant<GenD>(std::vector<double>(static_cast<std::size_t>(GenD::n), 0.0), 0.5, 1e-3,
                           17 + static_cast<std::uint64_t>(GenD::n), 0.0);
  return s;
}

}  // namespace obsynth_bench
