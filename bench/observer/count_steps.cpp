// Runs N steps of one observer, for instruction counting under valgrind --tool=callgrind:
//
//   count_steps generated|handwritten|expert float|double N          (seed 003 observers)
//   count_steps_chains chain<n>_stable|chain<n>_newton|chain<n>_newton_z float|double N
//   count_steps[_chains] OBSERVER_fixed_dt float|double N   the same on the fixed-dt samples
//                            (seed003: generated|handwritten|expert; chains: chain<n>_stable and
//                            chain<n>_stable_expert, the expert step of expert_chain.hpp), as
//                            in the *_fixed_dt benchmarks
//
// Setup (plant simulation, sample conversion) does not depend on N, so
// (Ir(2N) - Ir(N)) / N is the cost of one step() (plus the loop's few instructions, the same
// loop as in bench_observer). Prints the number of steps whose status was not ok and a checksum
// of the final estimate (so the work cannot be discarded).
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include "bench_loop.hpp"
#include "seed003.hpp"

namespace obsynth_bench {
#ifdef OBSYNTH_BENCH_CHAINS
bool count_chain_steps_double(const char* name, std::size_t steps, long* failures,
                              double* checksum);
bool count_chain_steps_float(const char* name, std::size_t steps, long* failures, double* checksum);
bool count_chain_steps_double_z(const char* name, std::size_t steps, long* failures,
                                double* checksum);
bool count_chain_steps_float_z(const char* name, std::size_t steps, long* failures,
                               double* checksum);
#endif

template <class Obs>
long count_seed003(std::size_t steps, double* checksum, bool fixed_dt) {
  static const SampleArrays<Obs> a(seed003_samples<Generated003<double>>());
  static const SampleArrays<Obs> af(seed003_samples_fixed_dt<Generated003<double>>());
  return run_steps<Obs>(
      fixed_dt ? af : a, [] { return make_observer<Obs>(); }, steps, checksum);
}

}  // namespace obsynth_bench

int main(int argc, char** argv) {
  using namespace obsynth_bench;
  if (argc != 4 || (std::strcmp(argv[2], "float") != 0 && std::strcmp(argv[2], "double") != 0)) {
    std::fprintf(stderr, "usage: %s (generated|handwritten|expert%s)[_fixed_dt] float|double N\n",
                 argv[0],
#ifdef OBSYNTH_BENCH_CHAINS
                 "|chain<n>_stable|chain<n>_newton|chain<n>_newton_z|chain<n>_stable_expert"
#else
                 ""
#endif
    );
    return 2;
  }
  std::string which = argv[1];
  const std::string suffix = "_fixed_dt";
  const bool fixed_dt = which.size() > suffix.size() &&
                        which.compare(which.size() - suffix.size(), suffix.size(), suffix) == 0;
  const bool dbl = std::strcmp(argv[2], "double") == 0;
  const std::size_t steps = std::strtoull(argv[3], nullptr, 10);
  long failures = 0;
  double checksum = 0;
  const std::string base = fixed_dt ? which.substr(0, which.size() - suffix.size()) : which;
  if (base == "generated") {
    failures = dbl ? count_seed003<Generated003<double>>(steps, &checksum, fixed_dt)
                   : count_seed003<Generated003<float>>(steps, &checksum, fixed_dt);
  } else if (base == "handwritten") {
    failures = dbl ? count_seed003<Handwritten003<double>>(steps, &checksum, fixed_dt)
                   : count_seed003<Handwritten003<float>>(steps, &checksum, fixed_dt);
  } else if (base == "expert") {
    failures = dbl ? count_seed003<Expert003<double>>(steps, &checksum, fixed_dt)
                   : count_seed003<Expert003<float>>(steps, &checksum, fixed_dt);
  } else {
#ifdef OBSYNTH_BENCH_CHAINS
    const char* w = which.c_str();
    const bool known = dbl ? count_chain_steps_double(w, steps, &failures, &checksum) ||
                                 count_chain_steps_double_z(w, steps, &failures, &checksum)
                           : count_chain_steps_float(w, steps, &failures, &checksum) ||
                                 count_chain_steps_float_z(w, steps, &failures, &checksum);
    if (!known) {
      std::fprintf(stderr, "unknown observer '%s'\n", which.c_str());
      return 2;
    }
#else
    std::fprintf(stderr, "unknown observer '%s' (chains are in count_steps_chains)\n",
                 which.c_str());
    return 2;
#endif
  }
  std::printf("%s %s steps=%zu failures=%ld checksum=%.6e\n", which.c_str(), argv[2], steps,
              failures, checksum);
  return 0;  // failed steps (e.g. Newton hitting its cap on the first step) are reported, not fatal
}
