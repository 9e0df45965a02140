// Runs a job in a forked worker with a hard per-stage deadline. GiNaC calls cannot be
// interrupted and GiNaC is not thread-safe, so a watchdog thread cannot stop a runaway
// normal(); killing a child process can. The child publishes its current stage through a
// shared page so the parent's diagnostic names the stage.
#pragma once

#include <functional>
#include <string>

namespace obsynth {

struct StageBeacon;
// Called by Budget::begin in the worker; no-op when no worker is running.
void publish_stage(const std::string& stage);

struct WorkerResult {
  int exit_code = 0;
  bool timed_out = false;
  std::string stage;  // the stage running when it timed out
};

// Runs job() in a child; kills it when one stage runs longer than stage_seconds (+ grace).
// on_timeout is called in the parent (e.g. to remove a staging directory).
WorkerResult run_in_worker(const std::function<int()>& job, double stage_seconds);

}  // namespace obsynth
