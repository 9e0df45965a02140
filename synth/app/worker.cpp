#include "app/worker.hpp"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <mutex>
#include <thread>

#include "foundation/budget.hpp"

namespace obsynth {

const char kStopReasonMarker[] = "@OBSYNTH-STOP-REASON@";

// The page shared by parent and child. Checkpoints alternate between two memory files, so
// that a child killed while writing one leaves the previous one intact.
struct StageBeacon {
  std::atomic<long long> start_ms;
  std::atomic<int> out_of_memory;    // set by the child's fatal-signal handler
  std::atomic<int> checkpoint_slot;  // -1: no checkpoint
  std::atomic<long long> checkpoint_size;
  char name[64];
};

namespace {

StageBeacon* g_beacon = nullptr;             // in the child only
int g_checkpoint_fds[2] = {-1, -1};          // in the child and the parent
char g_stage[64] = "start";                  // this process's last published stage
std::atomic<long long> g_stage_start_ms{0};  // when it began (steady clock)
// Guards g_stage and g_process_checkpoint against the watchdog thread of run_watched.
std::mutex g_process_mutex;
std::size_t g_memory_limit = 0;  // RLIMIT_AS applied to this process
// --in-process: the checkpoint and the diagnostic's tail, ready for the signal handler.
bool g_in_process = false;
std::string g_process_checkpoint, g_process_reason;
alignas(16) char g_signal_stack[1 << 16];
const std::size_t g_page_size = static_cast<std::size_t>(sysconf(_SC_PAGE_SIZE));

long long now_ms() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

const long long g_process_start_ms = now_ms();  // static initialisation: the run's start

// Whether the run has used up its total budget (0: none).
bool past_total_deadline(double total_seconds) {
  return total_seconds > 0 && now_ms() - g_process_start_ms >
                                  static_cast<long long>(total_seconds * 1000.0) - kTotalMarginMs;
}

// Fields of /proc/<pid>/statm in bytes (0: total program size, 1: resident set); 0 when
// unreadable. Async-signal-safe (open, read, close).
std::size_t statm_bytes(const char* path, int field) {
  const int fd = open(path, O_RDONLY);
  if (fd < 0) return 0;
  char buf[128];
  const ssize_t n = read(fd, buf, sizeof buf - 1);
  close(fd);
  if (n <= 0) return 0;
  std::size_t value = 0;
  int seen = 0;
  for (ssize_t i = 0; i < n; ++i) {
    if (buf[i] == ' ') {
      if (seen++ == field) break;
      value = 0;
    } else if (buf[i] >= '0' && buf[i] <= '9') {
      value = value * 10 + static_cast<std::size_t>(buf[i] - '0');
    }
  }
  return value * g_page_size;
}

void write_all(int fd, const char* p, std::size_t n) {
  while (n > 0) {
    const ssize_t w = write(fd, p, n);
    if (w <= 0) return;
    p += w;
    n -= static_cast<std::size_t>(w);
  }
}

// Writes text with every kStopReasonMarker replaced by reason (async-signal-safe).
void write_filled(int fd, const std::string& text, const std::string& reason) {
  const std::size_t m = sizeof kStopReasonMarker - 1;
  std::size_t from = 0;
  for (std::size_t i = 0; i + m <= text.size(); ++i)
    if (std::memcmp(text.data() + i, kStopReasonMarker, m) == 0) {
      write_all(fd, text.data() + from, i - from);
      write_all(fd, reason.data(), reason.size());
      from = i + m;
      i += m - 1;
    }
  write_all(fd, text.data() + from, text.size() - from);
}

// A fatal signal caused by memory exhaustion: malloc failed just before (GMP and FLINT abort
// on ENOMEM), or the address space is at the limit (a stack that cannot grow).
bool memory_exhausted(int saved_errno) {
  if (saved_errno == ENOMEM) return true;
  if (g_memory_limit == 0) return false;
  const std::size_t size = statm_bytes("/proc/self/statm", 0);
  return size + g_memory_limit / 16 >= g_memory_limit;
}

// Ends this process after a budget stop: the last checkpoint with the reason filled in on
// stdout, "obsynth: error: stage 'X' <reason>" on stderr, exit 1. Async-signal-safe.
[[noreturn]] void exit_with_process_stop(const std::string& reason) {
  write_filled(STDOUT_FILENO, g_process_checkpoint, reason);
  const char head[] = "obsynth: error: stage '";
  write_all(STDERR_FILENO, head, sizeof head - 1);
  write_all(STDERR_FILENO, g_stage, std::strlen(g_stage));
  write_all(STDERR_FILENO, "' ", 2);
  write_all(STDERR_FILENO, reason.data(), reason.size());
  write_all(STDERR_FILENO, "\n", 1);
  _exit(1);
}

void on_fatal_signal(int sig) {
  const int saved_errno = errno;
  if (memory_exhausted(saved_errno)) {
    const rlimit no_core{0, 0};
    setrlimit(RLIMIT_CORE, &no_core);
    if (g_beacon) g_beacon->out_of_memory.store(1);
    if (g_in_process) exit_with_process_stop(g_process_reason);
  }
  signal(sig, SIG_DFL);
  raise(sig);
}

void install_fatal_signal_handlers() {
  stack_t ss{};
  ss.ss_sp = g_signal_stack;
  ss.ss_size = sizeof g_signal_stack;
  sigaltstack(&ss, nullptr);
  struct sigaction sa {};
  sa.sa_handler = on_fatal_signal;
  sa.sa_flags = SA_ONSTACK | SA_RESETHAND;
  sigemptyset(&sa.sa_mask);
  for (int sig : {SIGABRT, SIGSEGV, SIGBUS}) sigaction(sig, &sa, nullptr);
}

// AddressSanitizer reserves terabytes of address space for its shadow memory, so an
// address-space limit would stop every sanitized run at start-up: there the resident-set
// guard of the parent is the memory budget.
#if defined(__SANITIZE_ADDRESS__)
constexpr bool kAddressSpaceLimit = false;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
constexpr bool kAddressSpaceLimit = false;
#else
constexpr bool kAddressSpaceLimit = true;
#endif
#else
constexpr bool kAddressSpaceLimit = true;
#endif

void limit_address_space(std::size_t bytes) {
  g_memory_limit = bytes;
  if (bytes == 0 || !kAddressSpaceLimit) return;
  rlimit rl{};
  if (getrlimit(RLIMIT_AS, &rl) != 0) return;
  rl.rlim_cur = rl.rlim_max == RLIM_INFINITY ? bytes : std::min<rlim_t>(bytes, rl.rlim_max);
  setrlimit(RLIMIT_AS, &rl);
}

std::string read_checkpoint(const StageBeacon& beacon) {
  const int slot = beacon.checkpoint_slot.load();
  if (slot < 0 || g_checkpoint_fds[slot] < 0) return {};
  std::string text(static_cast<std::size_t>(beacon.checkpoint_size.load()), '\0');
  const ssize_t n = pread(g_checkpoint_fds[slot], text.data(), text.size(), 0);
  if (n != static_cast<ssize_t>(text.size())) return {};
  return text;
}

// Runs the job in the (just forked) child and exits with its code.
[[noreturn]] void run_child(const std::function<int()>& job, StageBeacon* beacon,
                            std::size_t max_memory_bytes) {
  g_beacon = beacon;
  limit_address_space(max_memory_bytes);
  install_fatal_signal_handlers();
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

// The parent's side: waits for the child, enforcing the deadline and the resident-set guard.
// Sleeps up to 5 ms, waking at once when the child exits (a pidfd becomes readable then; where
// pidfds are not available, a plain sleep): a short analysis is not delayed by the polling.
void wait_a_tick(int pidfd) {
  if (pidfd >= 0) {
    pollfd p{pidfd, POLLIN, 0};
    poll(&p, 1, 5);
    return;
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(5));
}

struct PidFd {
  explicit PidFd(pid_t pid) : fd(static_cast<int>(syscall(SYS_pidfd_open, pid, 0))) {}
  ~PidFd() {
    if (fd >= 0) close(fd);
  }
  PidFd(const PidFd&) = delete;
  PidFd& operator=(const PidFd&) = delete;
  int fd;
};

// The deadline of the named stage, with the grace period.
long long stage_limit_ms(const WorkerLimits& limits, const char* stage) {
  return static_cast<long long>(
             stage_time_limit(stage, limits.stage_seconds, limits.canonical_stage_seconds) *
             1000.0) +
         500;
}

void watch_child(pid_t pid, StageBeacon& beacon, const WorkerLimits& limits, WorkerResult& res) {
  const std::string statm = "/proc/" + std::to_string(pid) + "/statm";
  const PidFd pidfd(pid);
  for (int tick = 0;; ++tick) {
    int status = 0;
    const pid_t r = waitpid(pid, &status, WNOHANG);
    if (r == pid) {
      if (WIFEXITED(status)) {
        res.exit_code = WEXITSTATUS(status);
        return;
      }
      res.signal = WIFSIGNALED(status) ? WTERMSIG(status) : 0;
      // Out of memory: flagged by the child's handler, or killed by the kernel's OOM killer
      // (a SIGKILL we did not send) while large.
      const bool oom = beacon.out_of_memory.load() != 0 ||
                       (res.signal == SIGKILL && limits.max_memory_bytes > 0 &&
                        2 * res.peak_rss_bytes >= limits.max_memory_bytes);
      res.exit_code = oom ? 1 : 2;  // otherwise a crash: an internal error
      if (oom) res.stop = WorkerStop::memory;
      res.stage = beacon.name;
      return;
    }
    if (r < 0) {
      res.exit_code = 2;
      return;
    }
    if (tick % 4 == 0) {
      const std::size_t rss = statm_bytes(statm.c_str(), 1);
      res.peak_rss_bytes = std::max(res.peak_rss_bytes, rss);
      if (limits.max_memory_bytes > 0 && rss > limits.max_memory_bytes)
        res.stop = WorkerStop::memory;
    }
    if (now_ms() - beacon.start_ms.load() > stage_limit_ms(limits, beacon.name))
      res.stop = WorkerStop::time;
    if (past_total_deadline(limits.total_seconds)) res.stop = WorkerStop::total_time;
    if (res.stop != WorkerStop::none) {
      res.stage = beacon.name;
      kill(pid, SIGKILL);
      waitpid(pid, &status, 0);
      res.exit_code = 1;
      return;
    }
    wait_a_tick(pidfd.fd);
  }
}

}  // namespace

void publish_stage(const std::string& stage) {
  {
    const std::lock_guard<std::mutex> lock(g_process_mutex);
    std::snprintf(g_stage, sizeof g_stage, "%s", stage.c_str());
  }
  g_stage_start_ms.store(now_ms());
  if (!g_beacon) return;
  std::snprintf(g_beacon->name, sizeof g_beacon->name, "%s", stage.c_str());
  g_beacon->start_ms.store(now_ms());
}

std::string current_stage() {
  const std::lock_guard<std::mutex> lock(g_process_mutex);
  return g_stage;
}

void publish_checkpoint(const std::string& text) {
  if (g_in_process) {
    const std::lock_guard<std::mutex> lock(g_process_mutex);
    g_process_checkpoint = text;
    return;
  }
  if (!g_beacon) return;
  if (text.empty()) {
    g_beacon->checkpoint_slot.store(-1);
    return;
  }
  const int slot = g_beacon->checkpoint_slot.load() == 0 ? 1 : 0;
  const int fd = g_checkpoint_fds[slot];
  if (fd < 0 || ftruncate(fd, 0) != 0) return;
  if (pwrite(fd, text.data(), text.size(), 0) != static_cast<ssize_t>(text.size())) return;
  g_beacon->checkpoint_size.store(static_cast<long long>(text.size()));
  g_beacon->checkpoint_slot.store(slot);
}

double seconds_since_start() {
  return static_cast<double>(now_ms() - g_process_start_ms) / 1000.0;
}

std::string total_time_budget_reason(double total_seconds) {
  char text[128];
  std::snprintf(text, sizeof text,
                "exceeded the total time budget of %g s (raise it with --total-seconds)",
                total_seconds);
  return text;
}

std::string fill_checkpoint(const std::string& checkpoint, const std::string& reason) {
  std::string out;
  const std::string marker = kStopReasonMarker;
  std::size_t from = 0;
  for (std::size_t at; (at = checkpoint.find(marker, from)) != std::string::npos;
       from = at + marker.size())
    out += checkpoint.substr(from, at - from) + reason;
  return out + checkpoint.substr(from);
}

WorkerResult run_in_worker(const std::function<int()>& job, const WorkerLimits& limits) {
  WorkerResult res;
  void* page =
      mmap(nullptr, sizeof(StageBeacon), PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS, -1, 0);
  if (page == MAP_FAILED) {  // no isolation available: run in-process
    res.exit_code = run_in_process(job, limits.max_memory_bytes);
    return res;
  }
  auto* beacon = new (page) StageBeacon;
  beacon->start_ms.store(now_ms());
  beacon->out_of_memory.store(0);
  beacon->checkpoint_slot.store(-1);
  beacon->checkpoint_size.store(0);
  std::snprintf(beacon->name, sizeof beacon->name, "%s", "start");
  for (int& fd : g_checkpoint_fds) fd = memfd_create("obsynth-checkpoint", MFD_CLOEXEC);
  std::fflush(stdout);
  std::fflush(stderr);
  const pid_t pid = fork();
  if (pid == 0) run_child(job, beacon, limits.max_memory_bytes);
  if (pid < 0)
    res.exit_code = run_in_process(job, limits.max_memory_bytes);
  else
    watch_child(pid, *beacon, limits, res);
  if (res.stop != WorkerStop::none) res.checkpoint = read_checkpoint(*beacon);
  for (int& fd : g_checkpoint_fds)
    if (fd >= 0) close(fd), fd = -1;
  munmap(page, sizeof(StageBeacon));
  return res;
}

int run_in_process(const std::function<int()>& job, std::size_t max_memory_bytes) {
  g_in_process = true;
  g_process_reason = memory_budget_reason(max_memory_bytes);
  limit_address_space(max_memory_bytes);
  install_fatal_signal_handlers();
  return job();
}

namespace {

// The watchdog thread of run_watched: wakes every 5 ms (at once when the job ends), and stops
// the process when the current stage has run past its deadline or the resident set is above
// the memory budget. It touches no GiNaC object: only atomics, the guarded stage and
// checkpoint, and write().
class WatchdogThread {
 public:
  explicit WatchdogThread(const WorkerLimits& limits)
      : limits_(limits),
        total_seconds_(limits.total_seconds),
        max_rss_(limits.max_memory_bytes),
        total_reason_(total_time_budget_reason(limits.total_seconds)),
        memory_reason_(memory_budget_reason(limits.max_memory_bytes)),
        thread_([this] { watch(); }) {}
  ~WatchdogThread() {
    {
      const std::lock_guard<std::mutex> lock(g_process_mutex);
      done_ = true;
    }
    wake_.notify_one();
    thread_.join();
  }
  WatchdogThread(const WatchdogThread&) = delete;
  WatchdogThread& operator=(const WatchdogThread&) = delete;

 private:
  void watch() {
    std::unique_lock<std::mutex> lock(g_process_mutex);
    for (int tick = 0; !done_; ++tick) {
      if (now_ms() - g_stage_start_ms.load() > stage_limit_ms(limits_, g_stage))
        exit_with_process_stop(stage_time_budget_reason(g_stage, limits_.stage_seconds,
                                                        limits_.canonical_stage_seconds));
      if (past_total_deadline(total_seconds_)) exit_with_process_stop(total_reason_);
      if (max_rss_ > 0 && tick % 4 == 0 && statm_bytes("/proc/self/statm", 1) > max_rss_)
        exit_with_process_stop(memory_reason_);
      wake_.wait_for(lock, std::chrono::milliseconds(5));
    }
  }

  const WorkerLimits limits_;
  const double total_seconds_;
  const std::size_t max_rss_;
  const std::string total_reason_, memory_reason_;
  bool done_ = false;  // guarded by g_process_mutex
  std::condition_variable wake_;
  std::thread thread_;  // last: starts once the members above are ready
};

}  // namespace

int run_watched(const std::function<int()>& job, const WorkerLimits& limits) {
  g_stage_start_ms.store(now_ms());
  const WatchdogThread watchdog(limits);
  return run_in_process(job, limits.max_memory_bytes);
}

}  // namespace obsynth
