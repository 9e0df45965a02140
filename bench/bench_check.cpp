// bench_check: Google Benchmark of the analysis pipeline (obsynth::analyse, in-process) on the
// scaled model families of families.hpp, n = 2, 4, 8, 12, 16.
//
// Each benchmark reports the per-stage times of analyse() (lie, observability, frame,
// conditions, diffeomorphism; ms per iteration) as user counters, plus the generic rank and
// whether the model came out linearizable.
//
// Budgets. Every analysis runs with AnalysisOptions.budget.stage_seconds = --stage_seconds
// (default 20, or $OBSYNTH_BENCH_STAGE_SECONDS). A stage that exceeds it throws
// obsynth::UserError, and the benchmark is skipped with SkipWithError naming the stage. The
// budget is checked cooperatively between GiNaC calls, so one long GiNaC call can overrun it;
// to keep the benchmark from hanging on such a size, each case is first probed once in a
// forked worker killed after stage_seconds (+0.5 s) in one stage (obsynth::run_in_worker, the
// same watchdog as the command line). Pass --probe=false to run purely in-process.
//
// Extra flags (besides Google Benchmark's own):
//   --stage_seconds=S    per-stage budget in seconds
//   --families=a,b       subset of chain,cubic,sine
//   --sizes=2,4,8        subset of sizes (any n >= 2)
//   --probe=true|false   the forked probe described above
#include <benchmark/benchmark.h>
#include <fmt/format.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "analysis/analysis.hpp"
#include "app/worker.hpp"
#include "families.hpp"
#include "foundation/diagnostics.hpp"
#include "front/parse.hpp"

namespace {

using namespace obsynth;
using namespace obsynth::bench;

struct Config {
  double stage_seconds = 20.0;
  bool probe = true;
  std::vector<Family> families = all_families();
  std::vector<int> sizes = default_sizes();
};

Config g_config;

const char* const kStages[] = {"lie", "observability", "frame", "conditions", "diffeomorphism"};

std::string first_diagnostic(const UserError& e) {
  if (!e.diagnostics().empty()) return e.diagnostics().front().message;
  return e.what();
}

AnalysisOptions options() {
  AnalysisOptions o;
  o.budget.stage_seconds = g_config.stage_seconds;
  return o;
}

// Runs one analysis in a forked worker with a hard per-stage deadline. Returns an empty
// string when it completes, else the reason (the budget diagnostic, or a crash).
std::string probe(Family f, int n) {
  int fds[2];
  if (pipe(fds) != 0) return {};  // no probe possible: fall back to in-process only
  const std::string text = family_model(f, n);
  const WorkerResult r = run_in_worker(
      [&]() -> int {
        close(fds[0]);
        std::string msg;
        int code = 0;
        try {
          const Model m = parse_model(text, model_file_name(f, n));
          (void)analyse(m, options());
        } catch (const UserError& e) {
          msg = first_diagnostic(e);
          code = 1;
        } catch (const std::exception& e) {
          msg = std::string("internal error: ") + e.what();
          code = 2;
        }
        if (!msg.empty()) {
          const ssize_t w = write(fds[1], msg.data(), msg.size());
          (void)w;
        }
        close(fds[1]);
        return code;
      },
      obsynth::WorkerLimits{g_config.stage_seconds, obsynth::default_memory_budget()});
  close(fds[1]);
  std::string msg;
  char buf[512];
  for (;;) {
    const ssize_t k = read(fds[0], buf, sizeof buf);
    if (k > 0) {
      msg.append(buf, static_cast<std::size_t>(k));
      continue;
    }
    if (k < 0 && errno == EINTR) continue;
    break;
  }
  close(fds[0]);
  if (r.stop == obsynth::WorkerStop::time)
    return fmt::format("stage '{}' exceeded its time budget of {:g} s (stopped by the watchdog)",
                       r.stage, g_config.stage_seconds);
  if (r.stop == obsynth::WorkerStop::memory)
    return fmt::format("stage '{}' exceeded its memory budget (stopped by the watchdog)", r.stage);
  if (r.exit_code != 0)
    return msg.empty() ? fmt::format("analysis failed with exit code {}", r.exit_code) : msg;
  return {};
}

void BM_check(benchmark::State& state, Family f, int n) {
  if (g_config.probe) {
    const std::string why = probe(f, n);
    if (!why.empty()) {
      state.SkipWithError(fmt::format("{}: {}", model_name(f, n), why).c_str());
      for (auto _ : state) {  // SkipWithError before the loop: the loop does not run
      }
      return;
    }
  }
  const std::string text = family_model(f, n);
  std::map<std::string, double> stage_ms;
  std::size_t rank = 0;
  bool linearizable = false;
  for (auto _ : state) {
    state.PauseTiming();
    // Fresh symbols for every iteration: nothing GiNaC cached on the previous run's
    // expressions is reused.
    const Model m = parse_model(text, model_file_name(f, n));
    state.ResumeTiming();
    try {
      const Analysis a = analyse(m, options());
      for (const auto& [s, ms] : a.timings_ms) stage_ms[s] += ms;
      rank = a.observability.generic_rank;
      linearizable = a.canonical.applicable && a.canonical.linearizable;
    } catch (const UserError& e) {
      state.SkipWithError(fmt::format("{}: {}", model_name(f, n), first_diagnostic(e)).c_str());
      break;
    }
  }
  if (state.error_occurred()) return;
  for (const char* s : kStages)
    state.counters[std::string(s) + "_ms"] = benchmark::Counter(
        stage_ms.count(s) ? stage_ms[s] : 0.0, benchmark::Counter::kAvgIterations);
  state.counters["rank"] = static_cast<double>(rank);
  state.counters["linearizable"] = linearizable ? 1.0 : 0.0;
  state.SetLabel(linearizable                         ? "linearizable"
                 : rank < static_cast<std::size_t>(n) ? fmt::format("rank {} < {}", rank, n)
                                                      : "not linearizable");
}

// --name=value parsing for our own flags; returns true and removes the argument when matched.
bool take_flag(int& argc, char** argv, int i, const char* name, std::string& value) {
  const std::string prefix = std::string("--") + name + "=";
  if (std::strncmp(argv[i], prefix.c_str(), prefix.size()) != 0) return false;
  value = argv[i] + prefix.size();
  for (int k = i; k + 1 < argc; ++k) argv[k] = argv[k + 1];
  --argc;
  return true;
}

std::vector<std::string> split(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ','))
    if (!item.empty()) out.push_back(item);
  return out;
}

bool parse_config(int& argc, char** argv) {
  if (const char* env = std::getenv("OBSYNTH_BENCH_STAGE_SECONDS"))
    g_config.stage_seconds = std::atof(env);
  for (int i = 1; i < argc;) {
    std::string v;
    if (take_flag(argc, argv, i, "stage_seconds", v)) {
      g_config.stage_seconds = std::atof(v.c_str());
    } else if (take_flag(argc, argv, i, "probe", v)) {
      g_config.probe = !(v == "false" || v == "0" || v == "no");
    } else if (take_flag(argc, argv, i, "families", v)) {
      g_config.families.clear();
      for (const auto& name : split(v)) {
        const auto f = parse_family(name);
        if (!f) {
          std::fprintf(stderr, "bench_check: unknown family '%s' (chain, cubic, sine)\n",
                       name.c_str());
          return false;
        }
        g_config.families.push_back(*f);
      }
    } else if (take_flag(argc, argv, i, "sizes", v)) {
      g_config.sizes.clear();
      for (const auto& s : split(v)) {
        const int n = std::atoi(s.c_str());
        if (n < 2) {
          std::fprintf(stderr, "bench_check: bad size '%s'\n", s.c_str());
          return false;
        }
        g_config.sizes.push_back(n);
      }
    } else {
      ++i;
    }
  }
  if (!(g_config.stage_seconds > 0)) {
    std::fprintf(stderr, "bench_check: --stage_seconds must be positive\n");
    return false;
  }
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (!parse_config(argc, argv)) return 1;
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::AddCustomContext("stage_seconds", fmt::format("{:g}", g_config.stage_seconds));
  for (Family f : g_config.families)
    for (int n : g_config.sizes)
      benchmark::RegisterBenchmark(fmt::format("check/{}/n:{}", family_name(f), n).c_str(),
                                   BM_check, f, n)
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime();
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
