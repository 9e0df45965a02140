// Diagnostics as data: user errors carry a source location and print gcc-style;
// internal invariants are asserted separately (OBSYNTH_ASSERT) and map to exit code 2.
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

namespace obsynth {

struct SourceLoc {
  std::string file;
  int line = 0;  // 1-based; 0 = no position (whole file / command line)
  int col = 0;   // 1-based
};

enum class Severity { error, warning, note };

struct Diagnostic {
  Severity severity = Severity::error;
  SourceLoc loc;
  std::string message;
};

// "file:line:col: error: message" (gcc style); position parts omitted when unknown.
std::string format_diagnostic(const Diagnostic& d);

// A user-facing failure: bad model, bad option, exceeded budget. Exit code 1.
class UserError : public std::runtime_error {
 public:
  explicit UserError(std::vector<Diagnostic> diags);
  UserError(SourceLoc loc, const std::string& message);
  const std::vector<Diagnostic>& diagnostics() const { return diags_; }

 private:
  std::vector<Diagnostic> diags_;
};

// A broken internal invariant: a bug in obsynth, never the user's fault. Exit code 2.
class InternalError : public std::logic_error {
 public:
  using std::logic_error::logic_error;
};

[[noreturn]] void internal_assert_failed(const char* cond, const char* file, int line,
                                         const std::string& msg);

}  // namespace obsynth

#define OBSYNTH_ASSERT(cond, msg)                                                     \
  do {                                                                                \
    if (!(cond)) ::obsynth::internal_assert_failed(#cond, __FILE__, __LINE__, (msg)); \
  } while (0)
