// Rigorous enclosures (synth/certify): cost and tightness.
//   bench_certify [--benchmark_filter=...]
// Counters: `ratio` = rigorous bound / largest value found at a point (1 = tight; the branch
// and bound stops at 1 + relative_gap), `boxes` = Arb box evaluations, `rigorous` = 1 when the
// bound is proven. For the Riccati certificate: `delta`, `rho` (lower bounds), `corollary`.
#include <benchmark/benchmark.h>

#include <filesystem>
#include <string>

#include "certify/enclosure.hpp"
#include "certify/riccati_certificate.hpp"
#include "front/parse.hpp"

using namespace obsynth;
using namespace obsynth::certify;

namespace {

std::size_t boxes_of(const std::string& method) {
  const auto p = method.find(", ");
  if (method.rfind("Arb balls", 0) != 0 || p == std::string::npos) return 0;
  return std::stoul(method.substr(p + 2));
}

// sup |sum_i x_{i+1} sin(x_i) + x_1 x_n| over [-2, 2]^n: a dependency-heavy sum.
GiNaC::ex sine_sum(const std::vector<GiNaC::symbol>& x) {
  GiNaC::ex e = x.front() * x.back();
  for (std::size_t i = 0; i + 1 < x.size(); ++i) e += x[i + 1] * sin(x[i]);
  return e;
}

Box cube(const std::vector<GiNaC::symbol>& x, double r) {
  Box b;
  for (const auto& s : x) {
    b.vars.push_back(s);
    b.ranges.push_back({-r, r});
  }
  return b;
}

std::vector<GiNaC::symbol> symbols(std::size_t n) {
  std::vector<GiNaC::symbol> x;
  for (std::size_t i = 0; i < n; ++i) x.emplace_back("x" + std::to_string(i + 1));
  return x;
}

void BM_SupAbsSineSum(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const auto budget = static_cast<std::size_t>(state.range(1));
  const auto x = symbols(n);
  const GiNaC::ex e = sine_sum(x);
  const Box box = cube(x, 2);
  Bound b;
  for (auto _ : state) b = sup_abs(e, box, {budget, 0.01});
  const Bound s = sup_abs_sampled(e, box, 4096);
  state.counters["ratio"] = b.value / s.value;
  state.counters["boxes"] = static_cast<double>(boxes_of(b.method));
  state.counters["rigorous"] = b.kind == BoundKind::rigorous;
}
BENCHMARK(BM_SupAbsSineSum)
    ->ArgsProduct({{2, 4, 8}, {64, 1024, 4096}})
    ->Unit(benchmark::kMillisecond);

// Lipschitz constant of the `sine` family field x_i' = x_{i+1} + sin(x_i).
void BM_LipschitzSineField(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const auto x = symbols(n);
  std::vector<GiNaC::ex> phi;
  for (std::size_t i = 0; i < n; ++i)
    phi.push_back((i + 1 < n ? GiNaC::ex(x[i + 1]) : 0) + sin(x[i]));
  const Box box = cube(x, 2);
  Bound b;
  for (auto _ : state) b = lipschitz_bound(phi, x, box);
  state.counters["bound"] = b.value;
  state.counters["boxes"] = static_cast<double>(boxes_of(b.method));
  state.counters["rigorous"] = b.kind == BoundKind::rigorous;
}
BENCHMARK(BM_LipschitzSineField)->Arg(2)->Arg(4)->Arg(8)->Unit(benchmark::kMillisecond);

// The whole Riccati certificate (default parameters) on every bundled model.
void BM_RiccatiCertificate(benchmark::State& state, std::string path) {
  const Model m = load_model(path);
  RiccatiCertificate c;
  try {
    for (auto _ : state) c = riccati_certificate(m);
  } catch (const std::exception& e) {
    state.SkipWithError(e.what());
    return;
  }
  state.counters["delta"] = c.delta.value;
  state.counters["rho"] = c.rho.value;
  state.counters["detectable"] = c.detectability.holds;
  state.counters["corollary"] = c.corollary_2_1;
  state.counters["rigorous"] = c.rigorous;
}

const int registered = [] {
  std::vector<std::filesystem::path> files;
  for (const auto& f :
       std::filesystem::directory_iterator(std::string(OBSYNTH_SOURCE_DIR) + "/models"))
    if (f.path().extension() == ".sym") files.push_back(f.path());
  std::sort(files.begin(), files.end());
  for (const auto& f : files)
    benchmark::RegisterBenchmark(("BM_RiccatiCertificate/" + f.stem().string()).c_str(),
                                 BM_RiccatiCertificate, f.string())
        ->Unit(benchmark::kMillisecond);
  return 0;
}();

}  // namespace

BENCHMARK_MAIN();
