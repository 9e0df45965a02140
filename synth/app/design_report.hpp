// The designs part of a report: which registered designs apply to a model and why (check),
// and the generated observers (main job). Renders what the registry's verdicts and the
// designs' ObserverSpecs say; nothing is re-derived here.
#pragma once

#include <nlohmann/json.hpp>

#include <map>
#include <string>
#include <vector>

#include "analysis/analysis.hpp"
#include "app/report.hpp"
#include "designs/registry.hpp"
#include "designs/spec.hpp"

namespace obsynth {

// One generated observer, as the report shows it.
struct GeneratedObserver {
  std::string method, file, class_name, summary, usage_example;
  bool c_language = false;  // --language c: a C struct, parameters in its `prm` member
  std::vector<ReportRow> rows;
  std::vector<RuntimeParam> params;
};

// Which designs' verdicts a report evaluates. The others get a "not evaluated" row (applies
// null, "evaluated": false) that says why.
struct VerdictScope {
  std::vector<std::string> only;  // empty: every design; else these methods only
  bool searches = true;           // run the verdicts that are certificate searches
  // Designs whose verdict a budget stopped in this run (auto passed over them): reported as not
  // evaluated, with the reason, instead of running out of the budget again.
  std::map<std::string, std::string> passed_over;
};

nlohmann::ordered_json design_verdicts_json(PlanSet& plans, const VerdictScope& scope = {});
// The registered designs with their traits and options, for `obsynth --list-methods --format
// json` (the CMake function validates METHOD and OPTIONS against it).
nlohmann::ordered_json methods_json();

// The same with a plan set of its own (default options).
nlohmann::ordered_json design_verdicts_json(const Analysis& a, const VerdictScope& scope = {});
// The free parameters' boxes: [{"name", "lo", "hi"}].
nlohmann::ordered_json parameter_box_json(const Model& m);
std::string render_design_verdicts(const nlohmann::ordered_json& verdicts, ReportFormat format);

// The full `check` report: the analysis and the design verdicts.
std::string render_check(const Analysis& a, ReportFormat format, const ReportOptions& opt,
                         const nlohmann::ordered_json& verdicts);

nlohmann::ordered_json generated_json(const std::vector<GeneratedObserver>& g);
std::string render_generated_markdown(const std::vector<GeneratedObserver>& g);

}  // namespace obsynth
