// The timed loop shared by every observer benchmark: one step() per iteration on precomputed,
// varying (dt_k, u_k, y_k), with benchmark::DoNotOptimize on the estimate (which also acts as a
// memory clobber, so the observer state is really stored and reloaded between steps, as in a
// firmware task that calls step() once per period).
#pragma once

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <string>

#include "bench_common.hpp"
#include "obsynth/status.hpp"

namespace obsynth_bench {

/// Estimation error after convergence: max |xh(t_k) - x(t_k)| over the second half of the
/// samples, and the number of steps whose status was not ok. Run outside the timed loop.
/// It includes the response to the samples' measurement noise (1e-3 on y), which the chains'
/// gains amplify steeply with n: with the noise, chain8_stable reads about 1.3 and chain7 0.17
/// for the generated and the expert step alike (the same observer); without it, about 4e-3 at
/// dt = 0.01 and 4e-4 at dt = 0.001 (the first-order error of holding u and y over a step).
template <class Obs, class Make>
void accuracy(const SampleArrays<Obs>& a, const SampleSet& s, Make&& make, double& max_err,
              int& failures) {
  Obs obs = make();
  obs.reset(a.xh0);
  max_err = 0;
  failures = 0;
  for (std::size_t k = 0; k + 1 < kSamples; ++k) {
    failures += obs.step(a.dt[k], a.u[k], a.y[k]) != obsynth::Status::ok;
    if (k >= kSamples / 2)
      for (int i = 0; i < Obs::n; ++i)
        max_err = std::max(
            max_err,
            std::fabs(
                static_cast<double>(obs.estimate()(i)) -
                s.x[(k + 1) * static_cast<std::size_t>(Obs::n) + static_cast<std::size_t>(i)]));
  }
}

template <class Obs, class Make>
void step_benchmark(benchmark::State& st, const SampleArrays<Obs>& a, const SampleSet& s,
                    Make&& make) {
  double max_err = 0;
  int acc_failures = 0;
  accuracy<Obs>(a, s, make, max_err, acc_failures);

  Obs obs = make();
  obs.reset(a.xh0);
  // raw pointers in locals: the clobber in DoNotOptimize does not force reloading them
  const auto* dt = a.dt.data();
  const auto* u = a.u.data();
  const auto* y = a.y.data();
  std::size_t i = 0;
  long failures = 0;
  for (auto _ : st) {
    failures += obs.step(dt[i], u[i], y[i]) != obsynth::Status::ok;
    benchmark::DoNotOptimize(obs.estimate());
    i = (i + 1) & (kSamples - 1);
  }
  st.counters["failures"] = static_cast<double>(failures);  // steps with status != ok (timed loop)
  st.counters["acc_failures"] = acc_failures;               // the same in the accuracy run
  st.counters["est_err"] = max_err;                         // after convergence, vs the true state
  st.counters["plant_max_abs_x"] = s.max_abs_x;
  if (!s.finite) st.SetLabel("WARNING: the plant simulation left the finite range");
}

}  // namespace obsynth_bench

namespace obsynth_bench {

/// The same loop as step_benchmark, untimed, for instruction counting (count_steps): N steps
/// cycling through the samples. Returns the number of steps whose status was not ok and leaves
/// the sum of the final estimate in *checksum.
template <class Obs, class Make>
__attribute__((noinline)) long run_steps(const SampleArrays<Obs>& a, Make&& make, std::size_t steps,
                                         double* checksum) {
  Obs obs = make();
  obs.reset(a.xh0);
  const auto* dt = a.dt.data();
  const auto* u = a.u.data();
  const auto* y = a.y.data();
  long failures = 0;
  for (std::size_t k = 0; k < steps; ++k) {
    const std::size_t i = k & (kSamples - 1);
    failures += obs.step(dt[i], u[i], y[i]) != obsynth::Status::ok;
    benchmark::DoNotOptimize(obs.estimate());
  }
  *checksum = static_cast<double>(obs.estimate().sum());
  return failures;
}

}  // namespace obsynth_bench
