// Per-stage time, expression-size and memory budgets. Stages check time and size
// cooperatively between GiNaC calls (a single GiNaC call cannot be interrupted); the command
// line additionally runs the job in a forked worker with a hard deadline and an address-space
// limit (see worker.hpp). Memory is not checked here: an allocation beyond the limit fails
// (std::bad_alloc), and the analysis turns that into a stop of the running stage.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <utility>

#include "foundation/diagnostics.hpp"

namespace obsynth {

// The canonical-form stages: `auto` can do without them, so they get a budget well inside the
// total one (a stall there must leave time for the designs that do not need them).
bool is_canonical_form_stage(const std::string& stage);
constexpr double kCanonicalStageSeconds = 15.0;

struct BudgetLimits {
  double stage_seconds = 60.0;  // per stage
  // Each canonical-form stage: min(this, stage_seconds).
  double canonical_stage_seconds = kCanonicalStageSeconds;
  std::size_t max_expression_size = 2000000;  // nodes in one stored expression
  std::size_t max_memory_bytes = 0;  // the process's address-space limit (0: none set); the
                                     // worker applies it, diagnostics quote it
};

// A stage ran out of one of its budgets. A UserError (exit 1) whose message is
// "stage '<stage>' <reason>".
class BudgetExceeded : public UserError {
 public:
  BudgetExceeded(const std::string& stage, const std::string& reason);
  const std::string& stage() const { return stage_; }
  const std::string& reason() const { return reason_; }

 private:
  std::string stage_, reason_;
};

// The time budget of one stage, in seconds.
double stage_time_limit(const std::string& stage, double stage_seconds,
                        double canonical_stage_seconds);

// Reasons, as they follow "stage 'X' " in diagnostics and reports.
std::string time_budget_reason(double stage_seconds);
// The reason for `stage`, quoting its own limit and the option that raises it.
std::string stage_time_budget_reason(const std::string& stage, double stage_seconds,
                                     double canonical_stage_seconds);
std::string memory_budget_reason(std::size_t max_memory_bytes);  // 0: "ran out of memory"

// An allocation failed: std::bad_alloc, or CLN's "Out of virtual memory." exception.
bool is_out_of_memory(const std::exception& e);

// MiB below 1 GiB, else GiB, to three significant digits: "512 MiB", "1.5 GiB", "15.6 GiB".
std::string format_memory_size(std::size_t bytes);
// "512M", "4G", "1.5GiB", "300000K", "4096MB": a decimal number and an optional unit
// K, M, G or T (binary multiples, case-insensitive, optionally followed by "iB" or "B");
// no unit means bytes. nullopt when malformed or out of range.
std::optional<std::size_t> parse_memory_size(const std::string& text);
// Half of the machine's physical memory (the default memory budget).
std::size_t default_memory_budget();

class Budget {
 public:
  // Told the name of each stage as it begins (the forked worker publishes it, so that its
  // watchdog's diagnostic names the stage); analysis does not depend on the worker.
  using StageListener = std::function<void(const std::string&)>;

  explicit Budget(BudgetLimits limits = {}, StageListener on_stage = {})
      : limits_(limits), on_stage_(std::move(on_stage)) {}

  // Starts timing a stage; ends the previous one.
  void begin(const std::string& stage);
  // Ends the current stage and records its time.
  void end();
  // Throws BudgetExceeded naming the stage if its time or the size limit is exceeded.
  void check(std::size_t expression_size = 0) const;

  const std::map<std::string, double>& timings_ms() const { return timings_; }
  const BudgetLimits& limits() const { return limits_; }
  const std::string& stage() const { return stage_; }

 private:
  BudgetLimits limits_;
  StageListener on_stage_;
  std::string stage_;
  std::chrono::steady_clock::time_point start_;
  std::map<std::string, double> timings_;
};

// A deterministic work budget: the allocations made by operator new on this thread while a
// WorkScope is open. A choice between code paths made on it (the automatic rank method: the
// symbolic chain, or the jets when it costs too much) is a pure function of the model: the same
// on a loaded and a quiet machine, which a wall-clock share is not. Past the limit a counted
// allocation throws WorkBudgetExceeded, again every 16 allocations (a caller that
// swallows one cannot run on unbounded); GiNaC calls that cannot be interrupted by a cooperative
// check are interrupted this way.
class WorkBudgetExceeded : public std::bad_alloc {
 public:
  const char* what() const noexcept override { return "work budget exceeded"; }
};

class WorkScope {
 public:
  explicit WorkScope(std::uint64_t max_allocations);
  ~WorkScope();  // restores the enclosing scope's counter (scopes nest)
  WorkScope(const WorkScope&) = delete;
  WorkScope& operator=(const WorkScope&) = delete;
  std::uint64_t used() const;  // allocations counted so far in this scope
  bool exceeded() const;       // past the limit (a throw may have been swallowed)

 private:
  std::uint64_t saved_count_, saved_limit_;
  bool saved_active_;
};

// Times a stage for the lifetime of the object.
class StageScope {
 public:
  StageScope(Budget& b, const std::string& stage) : b_(b) { b_.begin(stage); }
  ~StageScope() { b_.end(); }
  StageScope(const StageScope&) = delete;
  StageScope& operator=(const StageScope&) = delete;

 private:
  Budget& b_;
};

}  // namespace obsynth
