#include "foundation/budget.hpp"

#include <algorithm>

#include <fmt/format.h>
#include <unistd.h>

#include <cln/exception.h>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <new>

namespace {

// The open WorkScope of this thread. Constant-initialised (no TLS wrapper call on every
// allocation, usable before dynamic initialisation).
struct WorkCounter {
  std::uint64_t count = 0, limit = 0;
  bool active = false;
};
// Past the limit, one throw per this many allocations: a destructor that allocates while the
// exception unwinds must not throw again (std::terminate), a caller that swallowed it soon does.
constexpr std::uint64_t kWorkRethrowEvery = 16;
thread_local WorkCounter t_work;

}  // namespace

// The replaceable global allocation function, counting for WorkScope. libstdc++'s array and
// nothrow forms call this one. Its deallocation functions are replaced with it: free() must
// release what malloc() gave (AddressSanitizer's own operator delete reports a mismatch).
void* operator new(std::size_t size) {
  if (t_work.active && ++t_work.count > t_work.limit &&
      (t_work.count - t_work.limit - 1) % kWorkRethrowEvery == 0)
    throw obsynth::WorkBudgetExceeded();
  if (size == 0) size = 1;
  for (;;) {
    if (void* p = std::malloc(size)) return p;
    std::new_handler handler = std::get_new_handler();
    if (!handler) throw std::bad_alloc();
    handler();
  }
}

// The other forms, replaced too: a sanitizer runtime supplies its own for each one it intercepts,
// and every pair must agree on malloc() and free().
void* operator new[](std::size_t size) {
  return ::operator new(size);
}
void* operator new(std::size_t size, const std::nothrow_t&) noexcept {
  try {
    return ::operator new(size);
  } catch (...) {
    return nullptr;
  }
}
void* operator new[](std::size_t size, const std::nothrow_t& tag) noexcept {
  return ::operator new(size, tag);
}
void operator delete(void* p) noexcept {
  std::free(p);
}
void operator delete(void* p, std::size_t) noexcept {
  std::free(p);
}
void operator delete[](void* p) noexcept {
  std::free(p);
}
void operator delete[](void* p, std::size_t) noexcept {
  std::free(p);
}
void operator delete(void* p, const std::nothrow_t&) noexcept {
  std::free(p);
}
void operator delete[](void* p, const std::nothrow_t&) noexcept {
  std::free(p);
}

namespace obsynth {

BudgetExceeded::BudgetExceeded(const std::string& stage, const std::string& reason)
    : UserError(SourceLoc{}, fmt::format("stage '{}' {}", stage, reason)),
      stage_(stage),
      reason_(reason) {}

bool is_canonical_form_stage(const std::string& stage) {
  return stage == "frame" || stage == "conditions" || stage == "diffeomorphism";
}

double stage_time_limit(const std::string& stage, double stage_seconds,
                        double canonical_stage_seconds) {
  if (is_canonical_form_stage(stage) && canonical_stage_seconds > 0)
    return std::min(stage_seconds, canonical_stage_seconds);
  return stage_seconds;
}

std::string stage_time_budget_reason(const std::string& stage, double stage_seconds,
                                     double canonical_stage_seconds) {
  const double limit = stage_time_limit(stage, stage_seconds, canonical_stage_seconds);
  if (limit < stage_seconds)
    return fmt::format(
        "exceeded its time budget of {:g} s (a canonical-form stage; raise it with "
        "--canonical-seconds)",
        limit);
  return time_budget_reason(stage_seconds);
}

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

WorkScope::WorkScope(std::uint64_t max_allocations)
    : saved_count_(t_work.count), saved_limit_(t_work.limit), saved_active_(t_work.active) {
  t_work = WorkCounter{0, max_allocations, true};
}

WorkScope::~WorkScope() {
  const std::uint64_t inner = t_work.count;
  t_work = WorkCounter{saved_count_, saved_limit_, saved_active_};
  if (saved_active_) t_work.count += inner;  // an enclosing scope pays for the inner one too
}

std::uint64_t WorkScope::used() const {
  return t_work.count;
}

bool WorkScope::exceeded() const {
  return t_work.count > t_work.limit;
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
  if (!stage_.empty() &&
      s > stage_time_limit(stage_, limits_.stage_seconds, limits_.canonical_stage_seconds))
    throw BudgetExceeded(stage_, stage_time_budget_reason(stage_, limits_.stage_seconds,
                                                          limits_.canonical_stage_seconds));
  if (expression_size > limits_.max_expression_size)
    throw BudgetExceeded(
        stage_, fmt::format("exceeded its expression-size budget: an expression has {} nodes, "
                            "the limit is {} (raise it with --max-expression-size)",
                            expression_size, limits_.max_expression_size));
}

}  // namespace obsynth
