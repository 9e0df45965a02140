// Per-stage time and expression-size budgets. Stages check cooperatively between GiNaC
// calls (a single GiNaC call cannot be interrupted); the command line additionally runs the
// job in a forked worker with a hard deadline (see worker.hpp).
#pragma once

#include <chrono>
#include <cstddef>
#include <functional>
#include <map>
#include <string>
#include <utility>

#include "front/diagnostics.hpp"

namespace obsynth {

struct BudgetLimits {
  double stage_seconds = 60.0;                // per stage
  std::size_t max_expression_size = 2000000;  // nodes in one stored expression
};

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
  // Throws UserError naming the stage if its time or the size limit is exceeded.
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
