#include "analysis/budget.hpp"

#include <fmt/format.h>

namespace obsynth {

void Budget::begin(const std::string& stage) {
  if (!stage_.empty()) end();
  stage_ = stage;
  start_ = std::chrono::steady_clock::now();
  if (on_stage_) on_stage_(stage);
}

void Budget::end() {
  if (stage_.empty()) return;
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start_).count();
  timings_[stage_] += ms;
  stage_.clear();
}

void Budget::check(std::size_t expression_size) const {
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  if (!stage_.empty() && s > limits_.stage_seconds)
    throw UserError(SourceLoc{},
                    fmt::format("stage '{}' exceeded its time budget of {:g} s (raise it with "
                                "--stage-seconds)",
                                stage_, limits_.stage_seconds));
  if (expression_size > limits_.max_expression_size)
    throw UserError(
        SourceLoc{},
        fmt::format("stage '{}' exceeded its expression-size budget: an expression "
                    "has {} nodes, the limit is {} (raise it with --max-expression-size)",
                    stage_, expression_size, limits_.max_expression_size));
}

}  // namespace obsynth
