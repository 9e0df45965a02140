// Per-stage time and expression-size budgets. Stages check cooperatively between GiNaC
// calls (a single GiNaC call cannot be interrupted); the command line additionally runs the
// job in a forked worker with a hard deadline (see worker.hpp).
#pragma once

#include <chrono>
#include <cstddef>
#include <map>
#include <string>

#include "diagnostics.hpp"

namespace obsynth {

struct BudgetLimits {
  double stage_seconds = 60.0;                // per stage
  std::size_t max_expression_size = 2000000;  // nodes in one stored expression
};

class Budget {
 public:
  explicit Budget(BudgetLimits limits = {}) : limits_(limits) {}

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
