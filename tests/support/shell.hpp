// Running a shell command from a test (compiling and running emitted code): its stdout and
// stderr, prefixed with "FAILED(<status>): <command>" when it exits non-zero.
#pragma once

#include <cstdio>
#include <string>

namespace obsynth::testing {

inline std::string run_command(const std::string& cmd) {
  std::string out;
  FILE* p = popen((cmd + " 2>&1").c_str(), "r");
  if (!p) return "FAILED: popen";
  char buf[4096];
  while (std::fgets(buf, sizeof buf, p)) out += buf;
  const int rc = pclose(p);
  if (rc != 0) out = "FAILED(" + std::to_string(rc) + "): " + cmd + "\n" + out;
  return out;
}

}  // namespace obsynth::testing
