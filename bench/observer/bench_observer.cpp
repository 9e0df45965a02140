// ns per step() of canonical-form Luenberger observers (Google Benchmark).
//
//   seed003/generated/<S>    generated/slawinski17_canonical.hpp (checked-in obsynth output)
//   seed003/handwritten/<S>  bench/handwritten_seed003.hpp, configured with the same poles
//   chain<n>_<flavor>/<S>    constructed chains n = 2..8 (stable: closed-form T^-1; newton: no
//                            closed-form T^-1, so obsynth picks the x realisation), generated
//                            at build time (only in the bench_observer_chains build)
//   chain<n>_newton_z/<S>    the newton chains emitted with --realisation z (T^-1 by Newton)
// for S = double and float. Before timing, the generated and the hand-written seed 003 observers
// are run side by side and must agree to 1e-12 (double); otherwise the program exits with 1.
#include <benchmark/benchmark.h>

#include <cstdio>
#include <string>

#include "bench_loop.hpp"
#include "seed003.hpp"

#ifndef OBSYNTH_BENCH_FLAGS
#define OBSYNTH_BENCH_FLAGS "unknown"
#endif

namespace obsynth_bench {
#ifdef OBSYNTH_BENCH_CHAINS
void register_chain_benchmarks_double();
void register_chain_benchmarks_float();
void register_chain_benchmarks_double_z();
void register_chain_benchmarks_float_z();
#endif

namespace {

template <class Obs>
void seed003_benchmark(benchmark::State& st) {
  // generated and hand-written observers see the same samples of the same plant
  const SampleSet& s = seed003_samples<Generated003<double>>();
  static const SampleArrays<Obs> a(s);
  step_benchmark<Obs>(st, a, s, [] { return make_observer<Obs>(); });
}

template <class Obs>
void seed003_fixed_dt_benchmark(benchmark::State& st) {
  const SampleSet& s = seed003_samples_fixed_dt<Generated003<double>>();
  static const SampleArrays<Obs> a(s);
  step_benchmark<Obs>(st, a, s, [] { return make_observer<Obs>(); });
}

void register_seed003() {
  benchmark::RegisterBenchmark("seed003/generated/double", seed003_benchmark<Generated003<double>>);
  benchmark::RegisterBenchmark("seed003/handwritten/double",
                               seed003_benchmark<Handwritten003<double>>);
  benchmark::RegisterBenchmark("seed003/generated/float", seed003_benchmark<Generated003<float>>);
  benchmark::RegisterBenchmark("seed003/handwritten/float",
                               seed003_benchmark<Handwritten003<float>>);
  benchmark::RegisterBenchmark("seed003/expert/double", seed003_benchmark<Expert003<double>>);
  benchmark::RegisterBenchmark("seed003/expert/float", seed003_benchmark<Expert003<float>>);
  // Fixed sample period (the firmware case; issue 7's comparison): side by side in one run.
  benchmark::RegisterBenchmark("seed003_fixed_dt/generated/double",
                               seed003_fixed_dt_benchmark<Generated003<double>>);
  benchmark::RegisterBenchmark("seed003_fixed_dt/expert/double",
                               seed003_fixed_dt_benchmark<Expert003<double>>);
  benchmark::RegisterBenchmark("seed003_fixed_dt/handwritten/double",
                               seed003_fixed_dt_benchmark<Handwritten003<double>>);
  benchmark::RegisterBenchmark("seed003_fixed_dt/generated/float",
                               seed003_fixed_dt_benchmark<Generated003<float>>);
  benchmark::RegisterBenchmark("seed003_fixed_dt/expert/float",
                               seed003_fixed_dt_benchmark<Expert003<float>>);
  benchmark::RegisterBenchmark("seed003_fixed_dt/handwritten/float",
                               seed003_fixed_dt_benchmark<Handwritten003<float>>);
}

std::string describe(const char* scalar, const Agreement& r) {
  char buf[200];
  std::snprintf(buf, sizeof buf, "%s: max |xh_gen - xh_hand| = %.3g (max |xh| = %.3g), failures %d",
                scalar, r.max_abs_diff, r.max_abs_x, r.failures);
  return buf;
}

}  // namespace
}  // namespace obsynth_bench

int main(int argc, char** argv) {
  using namespace obsynth_bench;
  // Same observer? Compare the estimates of both implementations step by step first.
  constexpr std::size_t kCheckSteps = 1000;
  // The generated step is the exact zero-order-hold discretisation and the hand-written ones
  // are RK4: they agree up to RK4's truncation error (O(dt^5) per step, ~(|pole| dt)^5 / 120
  // relative: 6e-9 over 1000 steps with the poles -2.74, -3.43), not to rounding.
  const Agreement d = check_seed003_agreement<double>(kCheckSteps);
  const Agreement f = check_seed003_agreement<float>(kCheckSteps);
  const Agreement de = check_seed003_agreement<double, Expert003<double>>(kCheckSteps);
  std::fprintf(stderr, "seed003 agreement over %zu steps: %s; %s\n", kCheckSteps,
               describe("double", d).c_str(), describe("float", f).c_str());
  std::fprintf(stderr, "seed003 expert agreement: %s\n", describe("double", de).c_str());
  if (d.failures != 0 || f.failures != 0 || de.failures != 0 ||
      !(d.max_abs_diff <= 2e-8 * std::max(1.0, d.max_abs_x)) ||
      !(de.max_abs_diff <= 2e-8 * std::max(1.0, de.max_abs_x)) ||
      !(f.max_abs_diff <= 1e-4 * std::max(1.0, f.max_abs_x))) {
    std::fprintf(stderr,
                 "generated and hand-written seed 003 observers disagree: not timing them\n");
    return 1;
  }
  benchmark::AddCustomContext("compile_flags", OBSYNTH_BENCH_FLAGS);
  benchmark::AddCustomContext("seed003_agreement_double", describe("double", d));
  benchmark::AddCustomContext("seed003_agreement_float", describe("float", f));
  benchmark::AddCustomContext("poles",
                              "-2.74, -3.43 (K = [9.3982, 6.17]) for every seed003 observer");

  register_seed003();
#ifdef OBSYNTH_BENCH_CHAINS
  register_chain_benchmarks_double();
  register_chain_benchmarks_double_z();
  register_chain_benchmarks_float();
  register_chain_benchmarks_float_z();
#endif
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
