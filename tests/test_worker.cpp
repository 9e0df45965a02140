// The forked worker: memory sizes on the command line, the hard deadline with its checkpoint,
// and every way memory exhaustion surfaces (std::bad_alloc, CLN's exception, an abort after a
// failed malloc as GMP and FLINT do, a stack that cannot grow, a resident set above the
// budget) ending as a memory stop, never as a crash.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cln/exception.h>
#include <cln/integer.h>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "app/worker.hpp"
#include "foundation/budget.hpp"

using namespace obsynth;

namespace {

constexpr std::size_t MiB = std::size_t{1} << 20;

// 128 MiB above what this (test) process already maps, a multiple of 64 MiB.
std::size_t memory_budget() {
  std::size_t pages = 0;
  if (FILE* f = std::fopen("/proc/self/statm", "r")) {
    if (std::fscanf(f, "%zu", &pages) != 1) pages = 0;
    std::fclose(f);
  }
  const std::size_t bytes = pages * static_cast<std::size_t>(sysconf(_SC_PAGE_SIZE)) + 128 * MiB;
  return (bytes + 64 * MiB - 1) / (64 * MiB) * (64 * MiB);
}
const std::size_t budget = memory_budget();

// A total budget whose deadline falls `seconds` from now (it counts from the process's start).
double total_seconds_from_now(double seconds) {
  return seconds_since_start() + seconds;
}

// AddressSanitizer reserves terabytes of address space: the worker applies no address-space
// limit there (synth/app/worker.cpp), so the tests of what that limit triggers do not apply.
#if defined(__SANITIZE_ADDRESS__)
constexpr bool kSanitized = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
constexpr bool kSanitized = true;
#else
constexpr bool kSanitized = false;
#endif
#else
constexpr bool kSanitized = false;
#endif
#define SKIP_WITHOUT_ADDRESS_SPACE_LIMIT() \
  if (kSanitized) GTEST_SKIP() << "no address-space limit under AddressSanitizer"

// In stage "greedy": lifts the address-space limit (the watchdogs lower only the soft one), so
// that only the resident-set guard is left, then touches 3x the budget and waits to be stopped.
[[noreturn]] void grow_resident_set_past_the_limit() {
  publish_stage("greedy");
  rlimit rl{};
  getrlimit(RLIMIT_AS, &rl);
  rl.rlim_cur = rl.rlim_max;
  setrlimit(RLIMIT_AS, &rl);
  std::vector<char*> kept;
  for (std::size_t total = 0; total < 3 * budget; total += 4 * MiB) {
    kept.push_back(static_cast<char*>(std::malloc(4 * MiB)));
    std::memset(kept.back(), 1, 4 * MiB);
  }
  for (;;) pause();
}

// Takes address space until malloc fails; returns the blocks (never touched, so never resident).
std::vector<void*> exhaust_address_space() {
  std::vector<void*> blocks;
  blocks.reserve(1 << 16);
  for (std::size_t size = 64 * MiB; size >= 4096;) {
    if (void* p = std::malloc(size))
      blocks.push_back(p);
    else
      size /= 2;
  }
  return blocks;
}

int recurse(int depth) {
  volatile char frame[4096];
  frame[0] = static_cast<char>(depth);
  return recurse(depth + 1) + frame[0];
}

}  // namespace

TEST(MemorySize, ParsesUnitsAsBinaryMultiples) {
  EXPECT_EQ(parse_memory_size("512M"), 512 * MiB);
  EXPECT_EQ(parse_memory_size("4G"), 4096 * MiB);
  EXPECT_EQ(parse_memory_size("4g"), 4096 * MiB);
  EXPECT_EQ(parse_memory_size("1.5GiB"), 1536 * MiB);
  EXPECT_EQ(parse_memory_size("300000K"), std::size_t{300000} * 1024);
  EXPECT_EQ(parse_memory_size("4096MB"), 4096 * MiB);
  EXPECT_EQ(parse_memory_size("1T"), 1024 * 1024 * MiB);
  EXPECT_EQ(parse_memory_size("1048576"), MiB);
  for (const char* bad : {"", "M", "12X", "-5M", "1.2.3G", "5 M", "0", "G4", "4GG", "0x10M"})
    EXPECT_FALSE(parse_memory_size(bad).has_value()) << bad;
}

TEST(MemorySize, FormatsInMiBOrGiB) {
  EXPECT_EQ(format_memory_size(512 * MiB), "512 MiB");
  EXPECT_EQ(format_memory_size(1536 * MiB), "1.5 GiB");
  EXPECT_EQ(format_memory_size(4096 * MiB), "4 GiB");
  EXPECT_EQ(memory_budget_reason(256 * MiB),
            "exceeded its memory budget of 256 MiB (raise it with --max-memory)");
}

TEST(Worker, PassesExitCodesThrough) {
  for (int code : {0, 1, 2}) {
    const WorkerResult r = run_in_worker([code] { return code; }, {5, budget});
    EXPECT_EQ(r.exit_code, code);
    EXPECT_EQ(r.stop, WorkerStop::none);
  }
}

TEST(Worker, ACrashIsNotAMemoryStop) {
  SKIP_WITHOUT_ADDRESS_SPACE_LIMIT();  // the classification measures the address space
  const WorkerResult r = run_in_worker(
      [] {
        raise(SIGSEGV);
        return 0;
      },
      {5, budget});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.signal, SIGSEGV);
  EXPECT_EQ(r.stop, WorkerStop::none);
}

TEST(Worker, DeadlineKillsAndKeepsTheCheckpoint) {
  const WorkerResult r = run_in_worker(
      [] {
        publish_stage("slow");
        publish_checkpoint(std::string("old ") + kStopReasonMarker);
        publish_checkpoint(std::string("partial: ") + kStopReasonMarker + ".");
        for (;;) pause();
        return 0;
      },
      {0.2, budget});
  EXPECT_EQ(r.stop, WorkerStop::time);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.stage, "slow");
  EXPECT_EQ(fill_checkpoint(r.checkpoint, "out of time"), "partial: out of time.");
}

TEST(Worker, BadAllocUnderTheLimit) {
  SKIP_WITHOUT_ADDRESS_SPACE_LIMIT();
  const WorkerResult r = run_in_worker(
      [] {
        try {
          std::vector<char> v(2 * budget);
          return v[0] == 0 ? 3 : 4;
        } catch (const std::bad_alloc& e) {
          return is_out_of_memory(e) ? 5 : 6;
        }
      },
      {5, budget});
  EXPECT_EQ(r.exit_code, 5);
}

TEST(Worker, ClnAllocationFailureIsOutOfMemory) {
  SKIP_WITHOUT_ADDRESS_SPACE_LIMIT();
  const WorkerResult r = run_in_worker(
      [] {
        try {
          // 2^(8 budget): CLN allocates the result's digits itself, and its allocator throws.
          const cln::cl_I big = cln::cl_I(1) << cln::cl_I(static_cast<long>(8 * budget));
          return cln::zerop(big) ? 3 : 4;
        } catch (const cln::runtime_exception& e) {
          return is_out_of_memory(e) ? 5 : 6;
        } catch (const std::exception&) {
          return 7;
        }
      },
      {30, budget});
  EXPECT_EQ(r.exit_code, 5);
  EXPECT_EQ(r.stop, WorkerStop::none);
}

TEST(Worker, ClnArithmeticAbortingInGmpIsAMemoryStop) {
  SKIP_WITHOUT_ADDRESS_SPACE_LIMIT();
  const WorkerResult r = run_in_worker(
      [] {
        publish_stage("power");
        // 3^(2^31) has 3.4e9 bits: GMP's temporary storage inside CLN's multiplication fails,
        // and GMP's allocator aborts.
        const cln::cl_I big = cln::expt_pos(cln::cl_I(3), cln::cl_I(1) << 31);
        return cln::zerop(big) ? 3 : 4;
      },
      {30, budget});
  EXPECT_EQ(r.stop, WorkerStop::memory);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.stage, "power");
}

TEST(Worker, AbortAfterFailedMallocIsAMemoryStop) {
  SKIP_WITHOUT_ADDRESS_SPACE_LIMIT();
  // GMP's and FLINT's default allocators abort() when malloc returns null.
  const WorkerResult r = run_in_worker(
      [] {
        publish_stage("gmp");
        publish_checkpoint(std::string("before gmp: ") + kStopReasonMarker);
        void* p = std::malloc(4 * budget);
        if (!p) std::abort();
        std::free(p);
        return 0;
      },
      {5, budget});
  EXPECT_EQ(r.stop, WorkerStop::memory);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.stage, "gmp");
  EXPECT_EQ(fill_checkpoint(r.checkpoint, "m"), "before gmp: m");
}

TEST(Worker, StackOverflowAtTheLimitIsAMemoryStop) {
  SKIP_WITHOUT_ADDRESS_SPACE_LIMIT();
  const WorkerResult r = run_in_worker(
      [] {
        publish_stage("deep");
        const auto blocks = exhaust_address_space();
        return recurse(static_cast<int>(blocks.size()));
      },
      {5, budget});
  EXPECT_EQ(r.stop, WorkerStop::memory);
  EXPECT_EQ(r.stage, "deep");
}

TEST(Worker, ResidentSetGuardStopsAChildThatLiftedItsLimit) {
  SKIP_WITHOUT_ADDRESS_SPACE_LIMIT();
  const WorkerResult r = run_in_worker(
      [] {
        grow_resident_set_past_the_limit();
        return 0;
      },
      {30, budget});
  EXPECT_EQ(r.stop, WorkerStop::memory);
  EXPECT_EQ(r.stage, "greedy");
  EXPECT_GT(r.peak_rss_bytes, budget);
}

TEST(WorkerDeathTest, InProcessAbortAfterFailedMallocEndsWithTheDiagnostic) {
  SKIP_WITHOUT_ADDRESS_SPACE_LIMIT();
  EXPECT_EXIT(
      {
        run_in_process(
            [] {
              publish_stage("flint");
              void* p = std::malloc(4 * budget);
              if (!p) std::abort();
              std::free(p);
              return 0;
            },
            budget);
        std::exit(0);
      },
      ::testing::ExitedWithCode(1),
      "obsynth: error: stage 'flint' exceeded its memory budget of [0-9.]+ [MG]iB \\(raise it "
      "with --max-memory\\)");
}

// run_watched: the same limits, enforced by a thread in this process. A stop ends the
// process, so these run as death tests (each in its own child).
TEST(WorkerDeathTest, WatchedDeadlinePrintsTheCheckpointAndTheDiagnostic) {
  EXPECT_EXIT(
      {
        dup2(STDERR_FILENO, STDOUT_FILENO);  // the checkpoint goes to stdout: match it too
        run_watched(
            [] {
              publish_stage("slow");
              publish_checkpoint(std::string("partial: ") + kStopReasonMarker + ".\n");
              for (;;) pause();
              return 0;
            },
            {0.2, budget});
        std::exit(0);
      },
      ::testing::ExitedWithCode(1),
      "partial: exceeded its time budget of 0.2 s.*\n.*"
      "obsynth: error: stage 'slow' exceeded its time budget of 0.2 s");
}

TEST(WorkerDeathTest, WatchedResidentSetGuard) {
  SKIP_WITHOUT_ADDRESS_SPACE_LIMIT();
  EXPECT_EXIT(
      {
        run_watched(
            [] {
              grow_resident_set_past_the_limit();
              return 0;
            },
            {30, budget});
        std::exit(0);
      },
      ::testing::ExitedWithCode(1), "obsynth: error: stage 'greedy' exceeded its memory budget");
}

TEST(Worker, WatchedPassesExitCodesThroughAndEachStageHasItsOwnDeadline) {
  // Three stages of 0.3 s each under a 0.5 s budget per stage (+ 0.5 s grace): no stop.
  const int code = run_watched(
      [] {
        for (const char* stage : {"a", "b", "c"}) {
          publish_stage(stage);
          usleep(300000);
        }
        return 7;
      },
      {0.5, 0});
  EXPECT_EQ(code, 7);
}

// The total budget counts from the process's start, across stages (each within its own
// budget), and stops kTotalMarginMs early.
TEST(Worker, TotalBudgetStopsAcrossStages) {
  const WorkerResult r = run_in_worker(
      [] {
        for (int k = 0;; ++k) {
          publish_stage("stage" + std::to_string(k));
          usleep(200000);
        }
        return 0;
      },
      {5, budget, total_seconds_from_now(1.0)});
  EXPECT_EQ(r.stop, WorkerStop::total_time);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.stage, "stage0");
}

TEST(WorkerDeathTest, WatchedTotalBudget) {
  EXPECT_EXIT(
      {
        run_watched(
            [] {
              for (int k = 0;; ++k) {
                publish_stage("stage" + std::to_string(k));
                usleep(200000);
              }
              return 0;
            },
            {5, budget, total_seconds_from_now(1.0)});
        std::exit(0);
      },
      ::testing::ExitedWithCode(1),
      "stage 'stage[1-9]' exceeded the total time budget of [0-9.]+ s \\(raise it with "
      "--total-seconds\\)");
}
