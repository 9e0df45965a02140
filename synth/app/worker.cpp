#include "app/worker.hpp"

#include <signal.h>
#include <sys/mman.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <thread>

namespace obsynth {

struct StageBeacon {
  std::atomic<long long> start_ms;
  char name[64];
};

namespace {
StageBeacon* g_beacon = nullptr;

long long now_ms() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}
}  // namespace

void publish_stage(const std::string& stage) {
  if (!g_beacon) return;
  std::snprintf(g_beacon->name, sizeof g_beacon->name, "%s", stage.c_str());
  g_beacon->start_ms.store(now_ms());
}

WorkerResult run_in_worker(const std::function<int()>& job, double stage_seconds) {
  WorkerResult res;
  void* page =
      mmap(nullptr, sizeof(StageBeacon), PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS, -1, 0);
  if (page == MAP_FAILED) {
    res.exit_code = job();  // no isolation available: run in-process
    return res;
  }
  auto* beacon = new (page) StageBeacon;
  beacon->start_ms.store(now_ms());
  std::snprintf(beacon->name, sizeof beacon->name, "%s", "start");
  std::fflush(stdout);
  std::fflush(stderr);
  const pid_t pid = fork();
  if (pid < 0) {
    munmap(page, sizeof(StageBeacon));
    res.exit_code = job();
    return res;
  }
  if (pid == 0) {
    g_beacon = beacon;
    int code = 2;
    try {
      code = job();
    } catch (...) {
      code = 2;
    }
    std::fflush(stdout);
    std::fflush(stderr);
    _exit(code);
  }
  const long long limit_ms = static_cast<long long>(stage_seconds * 1000.0) + 500;
  for (;;) {
    int status = 0;
    const pid_t r = waitpid(pid, &status, WNOHANG);
    if (r == pid) {
      if (WIFEXITED(status))
        res.exit_code = WEXITSTATUS(status);
      else
        res.exit_code = 2;  // killed by a signal: a crash is an internal error
      break;
    }
    if (r < 0) {
      res.exit_code = 2;
      break;
    }
    if (now_ms() - beacon->start_ms.load() > limit_ms) {
      res.stage = beacon->name;
      kill(pid, SIGKILL);
      waitpid(pid, &status, 0);
      res.timed_out = true;
      res.exit_code = 1;
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  munmap(page, sizeof(StageBeacon));
  return res;
}

}  // namespace obsynth
