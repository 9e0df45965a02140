// Runs one command and measures it the way the check benchmark reports it: wall time from just
// before the fork to just after the child is reaped (steady clock), and the child's peak
// resident set (wait4's ru_maxrss). Standard output and error go to the given files, and the
// child runs under an address-space limit. Replaces a shell pipeline of a subshell, ulimit and
// /usr/bin/time -v, whose own 3-4 ms of start-up were a large part of a 5 ms check.
//
//   timed_run MEM_LIMIT_MIB STDOUT_FILE STDERR_FILE COMMAND [ARG...]
//
// Prints "<wall s> <peak RSS MiB> <exit status>" (exit status 128 + N for a signal N).
#include <fcntl.h>
#include <sys/resource.h>
#include <sys/time.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>

namespace {

[[noreturn]] void run_child(long long mem_limit_mib, const char* out, const char* err,
                            char** argv) {
  if (mem_limit_mib > 0) {
    const rlim_t bytes = static_cast<rlim_t>(mem_limit_mib) << 20;
    const rlimit rl{bytes, bytes};
    setrlimit(RLIMIT_AS, &rl);
  }
  const int fo = open(out, O_WRONLY | O_CREAT | O_TRUNC, 0644);
  const int fe = open(err, O_WRONLY | O_CREAT | O_TRUNC, 0644);
  if (fo < 0 || fe < 0 || dup2(fo, STDOUT_FILENO) < 0 || dup2(fe, STDERR_FILENO) < 0) _exit(127);
  close(fo);
  close(fe);
  execvp(argv[0], argv);
  _exit(127);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 5) {
    std::fprintf(stderr,
                 "usage: timed_run MEM_LIMIT_MIB STDOUT_FILE STDERR_FILE COMMAND [ARG...]\n");
    return 2;
  }
  const long long mem_limit_mib = std::atoll(argv[1]);
  const auto t0 = std::chrono::steady_clock::now();
  const pid_t pid = fork();
  if (pid < 0) {
    std::perror("timed_run: fork");
    return 2;
  }
  if (pid == 0) run_child(mem_limit_mib, argv[2], argv[3], argv + 4);
  int status = 0;
  rusage usage{};
  if (wait4(pid, &status, 0, &usage) != pid) {
    std::perror("timed_run: wait4");
    return 2;
  }
  const auto t1 = std::chrono::steady_clock::now();
  const int code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  std::printf("%.4f %.0f %d\n", std::chrono::duration<double>(t1 - t0).count(),
              static_cast<double>(usage.ru_maxrss) / 1024.0, code);
  return 0;
}
