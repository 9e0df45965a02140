#include "analysis/budget.hpp"

#include <fmt/format.h>
#include <unistd.h>

#include <cln/exception.h>
#include <cctype>
#include <cmath>
#include <new>

namespace obsynth {

BudgetExceeded::BudgetExceeded(const std::string& stage, const std::string& reason)
    : UserError(SourceLoc{}, fmt::format("stage '{}' {}", stage, reason)),
      stage_(stage),
      reason_(reason) {}

std::string time_budget_reason(double stage_seconds) {
  return fmt::format("exceeded its time budget of {:g} s (raise it with --stage-seconds)",
                     stage_seconds);
}

std::string memory_budget_reason(std::size_t max_memory_bytes) {
  if (max_memory_bytes == 0) return "ran out of memory";
  return fmt::format("exceeded its memory budget of {} (raise it with --max-memory)",
                     format_memory_size(max_memory_bytes));
}

bool is_out_of_memory(const std::exception& e) {
  if (dynamic_cast<const std::bad_alloc*>(&e)) return true;
  // CLN's allocator throws this when malloc fails (cl_malloc.cc).
  return dynamic_cast<const cln::runtime_exception*>(&e) &&
         std::string(e.what()) == "Out of virtual memory.";
}

std::string format_memory_size(std::size_t bytes) {
  constexpr double mib = 1024.0 * 1024.0, gib = 1024.0 * mib;
  if (bytes < gib) return fmt::format("{:.3g} MiB", bytes / mib);
  return fmt::format("{:.3g} GiB", bytes / gib);
}

std::optional<std::size_t> parse_memory_size(const std::string& text) {
  std::size_t i = 0;
  double value = 0;
  bool digits = false;
  for (; i < text.size() && std::isdigit(static_cast<unsigned char>(text[i])); ++i, digits = true)
    value = value * 10 + (text[i] - '0');
  if (i < text.size() && text[i] == '.') {
    double scale = 0.1;
    for (++i; i < text.size() && std::isdigit(static_cast<unsigned char>(text[i]));
         ++i, scale /= 10, digits = true)
      value += (text[i] - '0') * scale;
  }
  if (!digits) return std::nullopt;
  std::string unit;
  for (; i < text.size(); ++i) unit += static_cast<char>(std::toupper(text[i]));
  double multiplier = 1;
  if (!unit.empty() && unit != "B") {
    const std::string prefixes = "KMGT";
    const auto power = prefixes.find(unit[0]);
    const std::string rest = unit.substr(1);
    if (power == std::string::npos || !(rest.empty() || rest == "B" || rest == "IB"))
      return std::nullopt;
    multiplier = std::pow(1024.0, static_cast<double>(power + 1));
  }
  const double bytes = std::floor(value * multiplier);
  if (!(bytes >= 1) || bytes > 9.0e18) return std::nullopt;
  return static_cast<std::size_t>(bytes);
}

std::size_t default_memory_budget() {
  const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGE_SIZE);
  if (pages <= 0 || page <= 0) return 0;
  return static_cast<std::size_t>(pages) * static_cast<std::size_t>(page) / 2;
}

void Budget::begin(const std::string& stage) {
  if (!stage_.empty()) end();
  stage_ = stage;
  // The listener may checkpoint a report: that is not the stage's time.
  if (on_stage_) on_stage_(stage);
  start_ = std::chrono::steady_clock::now();
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
    throw BudgetExceeded(stage_, time_budget_reason(limits_.stage_seconds));
  if (expression_size > limits_.max_expression_size)
    throw BudgetExceeded(
        stage_, fmt::format("exceeded its expression-size budget: an expression has {} nodes, "
                            "the limit is {} (raise it with --max-expression-size)",
                            expression_size, limits_.max_expression_size));
}

}  // namespace obsynth
