// Benchmarks of the generated canonical observers of the constructed chains n = 2..8, for one
// header set (see CMakeLists.txt): compiled once per set, e.g. with the headers emitted by
// `obsynth --precision double` and Scalar = double, or by `--precision float` and
// Scalar = float (float headers carry float literals and a float-sized Newton tolerance, 1e-6
// instead of 1e-13, which a float Newton iteration could never meet), or with
// `--realisation z` (T^-1 by runtime Newton; benchmark names get the suffix "_z").
// The sets declare the same namespaces and classes, so all but one are compiled with the
// top-level namespace renamed (-Dobsynth_gen=obsynth_gen_<set>): no ODR clash between them.
//
// chains_list.hpp (written by CMake) includes the set's headers and defines
//   OBSYNTH_CHAINS(X)  ->  X(chain2_stable, Chain2StableCanonical) X(chain2_newton, ...) ...
#include <benchmark/benchmark.h>

#include <cstring>
#include <string>

#include "bench_loop.hpp"
#include "chains_list.hpp"
#include "expert_chain.hpp"

#define OBSYNTH_STR2(x) #x
#define OBSYNTH_STR(x) OBSYNTH_STR2(x)

namespace obsynth_bench {
namespace {

using Scalar = OBSYNTH_CHAIN_SCALAR;

template <template <class> class Obs>
const SampleArrays<Obs<Scalar>>& chain_arrays() {
  // the plant is simulated in double through the header's own f, g, h
  static const SampleArrays<Obs<Scalar>> a(chain_samples<Obs<double>>());
  return a;
}

template <template <class> class Obs>
void chain_benchmark(benchmark::State& st) {
  step_benchmark<Obs<Scalar>>(st, chain_arrays<Obs>(), chain_samples<Obs<double>>(),
                              [] { return Obs<Scalar>(); });
}

// Fixed sample period, the generated step and the expert one (closed-form T^-1 chains only).
template <class Obs, class GenD>
void chain_fixed_dt_benchmark(benchmark::State& st) {
  static const SampleArrays<Obs> a(chain_samples_fixed_dt<GenD>());
  step_benchmark<Obs>(st, a, chain_samples_fixed_dt<GenD>(), [] { return Obs(); });
}

template <template <class> class Gen>
void register_fixed_dt(const std::string& name) {
  if constexpr (has_closed_form_z<typename Gen<Scalar>::F>::value) {
    const std::string s = OBSYNTH_STR(OBSYNTH_CHAIN_SCALAR);
    benchmark::RegisterBenchmark((name + "_fixed_dt/generated/" + s).c_str(),
                                 chain_fixed_dt_benchmark<Gen<Scalar>, Gen<double>>);
    benchmark::RegisterBenchmark(
        (name + "_fixed_dt/expert/" + s).c_str(),
        chain_fixed_dt_benchmark<ExpertCanonical<Gen<Scalar>>, Gen<double>>);
  }
}

}  // namespace

void OBSYNTH_CHAIN_REGISTER() {
#define OBSYNTH_REGISTER_ONE(ns, cls)                                                          \
  benchmark::RegisterBenchmark(#ns OBSYNTH_CHAIN_SUFFIX "/" OBSYNTH_STR(OBSYNTH_CHAIN_SCALAR), \
                               chain_benchmark<obsynth_gen::ns::cls>);
  OBSYNTH_CHAINS(OBSYNTH_REGISTER_ONE)
#undef OBSYNTH_REGISTER_ONE
#define OBSYNTH_REGISTER_FIXED(ns, cls) \
  register_fixed_dt<obsynth_gen::ns::cls>(#ns OBSYNTH_CHAIN_SUFFIX);
  OBSYNTH_CHAINS(OBSYNTH_REGISTER_FIXED)
#undef OBSYNTH_REGISTER_FIXED
}

namespace {
/// count_steps on the fixed-dt samples of the *_fixed_dt benchmarks: the generated step
/// (name + "_fixed_dt") or the expert one (name + "_expert_fixed_dt"); false if neither.
template <template <class> class Gen>
bool count_fixed_dt(const std::string& model, const char* name, std::size_t steps, long* failures,
                    double* checksum) {
  using G = Gen<Scalar>;
  if (model + "_fixed_dt" == name) {
    static const SampleArrays<G> a(chain_samples_fixed_dt<Gen<double>>());
    *failures = run_steps<G>(
        a, [] { return G(); }, steps, checksum);
    return true;
  }
  if constexpr (has_closed_form_z<typename G::F>::value) {
    using E = ExpertCanonical<G>;
    if (model + "_expert_fixed_dt" == name) {
      static const SampleArrays<E> a(chain_samples_fixed_dt<Gen<double>>());
      *failures = run_steps<E>(
          a, [] { return E(); }, steps, checksum);
      return true;
    }
  }
  return false;
}
}  // namespace

/// For count_steps: runs `steps` steps of the named chain observer (model name plus the set's
/// suffix, e.g. chain5_newton_z; with "_fixed_dt" or "_expert_fixed_dt" appended, the steps of
/// the *_fixed_dt benchmarks); false if the name is unknown.
bool OBSYNTH_CHAIN_COUNT(const char* name, std::size_t steps, long* failures, double* checksum) {
#define OBSYNTH_COUNT_FIXED(ns, cls)                                                        \
  if (count_fixed_dt<obsynth_gen::ns::cls>(#ns OBSYNTH_CHAIN_SUFFIX, name, steps, failures, \
                                           checksum))                                       \
    return true;
  OBSYNTH_CHAINS(OBSYNTH_COUNT_FIXED)
#undef OBSYNTH_COUNT_FIXED
#define OBSYNTH_COUNT_ONE(ns, cls)                                                           \
  if (std::strcmp(name, #ns OBSYNTH_CHAIN_SUFFIX) == 0) {                                    \
    *failures = run_steps<obsynth_gen::ns::cls<Scalar>>(                                     \
        chain_arrays<obsynth_gen::ns::cls>(), [] { return obsynth_gen::ns::cls<Scalar>(); }, \
        steps, checksum);                                                                    \
    return true;                                                                             \
  }
  OBSYNTH_CHAINS(OBSYNTH_COUNT_ONE)
#undef OBSYNTH_COUNT_ONE
  return false;
}

}  // namespace obsynth_bench
