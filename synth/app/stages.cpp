#include "app/stages.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cstdio>

#include "designs/registry.hpp"
#include "foundation/budget.hpp"

namespace obsynth {

namespace {

struct StageText {
  DesignStage stage;
  const char* suffix;  // after the method name
  const char* clause;  // why auto passes over the design
};
constexpr StageText kStages[] = {
    {DesignStage::verdict, " verdict", "its verdict stopped: "},
    {DesignStage::design, " design", "it applies, but its build stopped: "},
    {DesignStage::trial, " trial", "it applies, but its closed-loop trial stopped: "}};

const StageText& text_of(DesignStage stage) {
  for (const auto& t : kStages)
    if (t.stage == stage) return t;
  return kStages[0];
}

bool asks(const std::vector<std::string>& methods, const char* name) {
  return std::find(methods.begin(), methods.end(), name) != methods.end();
}

}  // namespace

std::string design_stage_name(const std::string& method, DesignStage stage) {
  return method + text_of(stage).suffix;
}

std::optional<StoppedDesignStage> parse_design_stage(const std::string& stage_name) {
  for (const auto& t : kStages) {
    const std::string suffix = t.suffix;
    if (stage_name.size() > suffix.size() &&
        stage_name.compare(stage_name.size() - suffix.size(), suffix.size(), suffix) == 0)
      return StoppedDesignStage{stage_name.substr(0, stage_name.size() - suffix.size()), t.stage};
  }
  return std::nullopt;
}

std::string passed_over_clause(DesignStage stage) {
  return text_of(stage).clause;
}

bool verdict_stopped(const ExcludedDesign& e) {
  return e.reason.rfind(passed_over_clause(DesignStage::verdict), 0) == 0;
}

bool may_skip_canonical_form(const std::vector<std::string>& methods) {
  return methods.empty() || asks(methods, "auto") || asks(methods, "all");
}

AfterStop after_stop(const std::vector<std::string>& methods, const std::string& stage,
                     const std::string& reason, RetryState& state) {
  const std::string why = fmt::format("stage '{}' {}", stage, reason);
  if (state.canonical_skipped.empty() && may_skip_canonical_form(methods) &&
      is_canonical_form_stage(stage)) {
    std::fprintf(stderr, "obsynth: note: %s; continuing without the canonical form\n", why.c_str());
    state.canonical_skipped = why;
    return AfterStop::rerun;
  }
  const auto design = parse_design_stage(stage);
  const bool auto_asked = methods.empty() || asks(methods, "auto");
  if (auto_asked && design && state.excluded.size() < design_registry().size()) {
    std::fprintf(stderr, "obsynth: note: %s; auto tries the next design\n", why.c_str());
    state.excluded.push_back({design->method, passed_over_clause(design->stage) + why});
    return AfterStop::rerun;
  }
  return AfterStop::end;
}

}  // namespace obsynth
