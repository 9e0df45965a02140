// Runs a job in a forked worker with a hard per-stage deadline and a memory limit. GiNaC
// calls cannot be interrupted and GiNaC is not thread-safe, so a watchdog thread cannot stop a
// runaway normal(); killing a child process can. The child publishes its current stage
// through a shared page so the parent's diagnostic names the stage, and may publish a
// checkpoint (the report of the stages completed so far) that the parent prints when it has
// to stop the child, so that a hard stop keeps what the earlier stages found.
//
// Memory: the child runs under RLIMIT_AS, so an allocation beyond the budget fails. Most
// failures surface as std::bad_alloc (or CLN's "Out of virtual memory." exception), which
// the analysis turns into a stop of the running stage. GMP and FLINT abort() instead, and a
// stack that cannot grow raises SIGSEGV: the child's signal handler flags these as memory
// exhaustion when errno is ENOMEM or the address space is at the limit. The parent also
// samples the child's resident set (/proc/<pid>/statm) and kills it above the budget.
#pragma once

#include <cstddef>
#include <functional>
#include <string>

namespace obsynth {

// Called by Budget::begin in the worker (through AnalysisOptions::on_stage). Also records the
// stage in this process, for the --in-process memory diagnostic.
void publish_stage(const std::string& stage);
// The stage last published in this process.
std::string current_stage();

// Marks where a checkpoint's text names the reason of the stop; the parent replaces it.
extern const char kStopReasonMarker[];
// Replaces the text the parent prints to stdout if it has to stop this worker (empty: print
// nothing). No-op outside a worker, except under run_in_process (see there).
void publish_checkpoint(const std::string& text);

struct WorkerLimits {
  double stage_seconds = 60;         // hard deadline per stage (plus a grace period)
  std::size_t max_memory_bytes = 0;  // address-space limit of the child (0: none)
  // The whole run, counted from this process's start, ends within this many seconds (0: no
  // limit): the stop comes kTotalMarginMs early, to leave time for the partial report.
  double total_seconds = 0;
  double canonical_stage_seconds = 0;  // canonical-form stages: min(this, stage_seconds); 0: same
};
constexpr long long kTotalMarginMs = 300;

enum class WorkerStop { none, time, memory, total_time };

// Seconds since this process started (the origin of WorkerLimits::total_seconds).
double seconds_since_start();

// "exceeded the total time budget of S s (raise it with --total-seconds)".
std::string total_time_budget_reason(double total_seconds);

struct WorkerResult {
  int exit_code = 0;
  WorkerStop stop = WorkerStop::none;  // the parent stopped the child, or it died of memory
  std::string stage;                   // the stage running when it was stopped
  std::string checkpoint;              // the child's last checkpoint (when stopped)
  int signal = 0;                      // the signal that ended a crashed child
  std::size_t peak_rss_bytes = 0;      // largest resident set sampled
};

// Runs job() in a child under the limits; job's return value is the exit code.
WorkerResult run_in_worker(const std::function<int()>& job, const WorkerLimits& limits);

// Runs job() in this process under the memory limit (RLIMIT_AS on this process, which stays
// in force; 0: none). An abort or stack overflow caused by memory exhaustion prints the last
// checkpoint and "obsynth: error: stage 'X' exceeded its memory budget of ...", exit 1.
int run_in_process(const std::function<int()>& job, std::size_t max_memory_bytes);

// Runs job() in this process under the same limits as run_in_worker, enforced by a watchdog
// thread instead of a parent process. At a time (stage or total) or resident-set stop the
// thread prints the last checkpoint (with the reason) and "obsynth: error: stage 'X'
// <reason>", and ends the process with exit 1; memory exhaustion is handled as in
// run_in_process. The thread never interrupts GiNaC (which cannot be interrupted and is not
// thread-safe): like the parent's SIGKILL it ends the process, touching only atomics, the
// guarded stage name and checkpoint, and write(). For jobs that a stop ends anyway (check,
// simulate) this saves the fork, 1-2 ms of a 5 ms check; a caller that goes on after a stop
// (the main job's fallbacks) needs run_in_worker.
int run_watched(const std::function<int()>& job, const WorkerLimits& limits);

// The checkpoint with every kStopReasonMarker replaced by reason.
std::string fill_checkpoint(const std::string& checkpoint, const std::string& reason);

}  // namespace obsynth
