#include "app/design_report.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>

#include "designs/registry.hpp"
#include "symbolic/expr_print.hpp"

namespace obsynth {

namespace {

nlohmann::ordered_json not_evaluated(const std::string& method, const std::string& why) {
  return {{"method", method}, {"applies", nullptr}, {"evaluated", false}, {"reasons", {why}}};
}

}  // namespace

nlohmann::ordered_json methods_json() {
  nlohmann::ordered_json methods = nlohmann::ordered_json::array();
  for (const auto& d : design_registry()) {
    nlohmann::ordered_json options = nlohmann::ordered_json::array();
    for (const auto& o : d.options)
      options.push_back({{"name", o.name},
                         {"qualified", qualified_option_name(d, o.name)},
                         {"help", o.help},
                         {"default", o.default_text}});
    methods.push_back({{"name", d.name},
                       {"summary", d.summary},
                       {"in_auto", d.in_all},
                       {"needs_canonical_form", d.needs_canonical_form},
                       {"max_outputs", d.max_outputs},
                       {"outputs_note", d.outputs_note},
                       {"accepts_feedthrough", d.accepts_feedthrough},
                       {"observes_output_offset", d.observes_output_offset},
                       {"observes_along_inputs", d.observes_along_inputs},
                       {"options", options}});
  }
  return {{"methods", methods}, {"planned", planned_methods()}};
}

nlohmann::ordered_json design_verdicts_json(const Analysis& a, const VerdictScope& scope) {
  PlanSet plans(a, DesignOptions{});
  return design_verdicts_json(plans, scope);
}

nlohmann::ordered_json design_verdicts_json(PlanSet& plans, const VerdictScope& scope) {
  nlohmann::ordered_json j = nlohmann::ordered_json::array();
  for (const auto& d : design_registry()) {
    const auto& only = scope.only;
    if (!only.empty() && std::find(only.begin(), only.end(), d.name) == only.end()) {
      j.push_back(not_evaluated(
          d.name, fmt::format("only --method {} was requested (`obsynth check --certify` "
                              "evaluates every design)",
                              fmt::join(only, ","))));
      continue;
    }
    if (const auto it = scope.passed_over.find(d.name); it != scope.passed_over.end()) {
      j.push_back(not_evaluated(d.name, it->second));
      continue;
    }
    if (d.verdict_searches && !scope.searches) {
      j.push_back(not_evaluated(
          d.name, fmt::format("its verdict is a certificate search or a symbolic construction "
                              "(up to seconds): `obsynth check --certify`, or the main job with "
                              "--method {}, runs it",
                              d.name)));
      continue;
    }
    const Verdict& v = plans.verdict(d, scope.searches);
    nlohmann::ordered_json e = {{"method", d.name}, {"applies", v.applies}, {"reasons", v.reasons}};
    if (v.applies) {
      e["guarantee"] = guarantee_name(v.guarantee);
      if (!v.guarantee_text.empty()) e["guarantee_reason"] = v.guarantee_text;
    }
    j.push_back(e);
  }
  for (const auto& name : planned_methods())
    j.push_back({{"method", name},
                 {"applies", nullptr},
                 {"reasons", {"not implemented in this version of obsynth"}}});
  return j;
}

namespace {

std::string verdict_word(const nlohmann::ordered_json& v) {
  if (v.contains("evaluated")) return "not evaluated";
  if (v["applies"].is_null()) return "planned";
  return v["applies"].get<bool>() ? "applies" : "does not apply";
}

}  // namespace

std::string render_design_verdicts(const nlohmann::ordered_json& verdicts, ReportFormat format) {
  std::string out;
  switch (format) {
    case ReportFormat::json:
      return verdicts.dump(2);
    case ReportFormat::text:
      out = "\nObserver designs\n";
      for (const auto& v : verdicts)
        out += fmt::format("  {:<24} {}: {}\n", v["method"].get<std::string>(), verdict_word(v),
                           fmt::join(v["reasons"].get<std::vector<std::string>>(), "; "));
      return out;
    case ReportFormat::markdown:
      out = "\n## Observer designs\n\n| method | verdict | why |\n|---|---|---|\n";
      for (const auto& v : verdicts)
        out += fmt::format("| `{}` | {} | {} |\n", v["method"].get<std::string>(), verdict_word(v),
                           fmt::join(v["reasons"].get<std::vector<std::string>>(), "; "));
      return out;
    case ReportFormat::latex:
      out = "\n\\subsection*{Observer designs}\n\\begin{itemize}\n";
      for (const auto& v : verdicts)
        out +=
            fmt::format("  \\item \\texttt{{{}}}: {} ({})\n",
                        latex_text(v["method"].get<std::string>()), verdict_word(v),
                        latex_text(fmt::format(
                            "{}", fmt::join(v["reasons"].get<std::vector<std::string>>(), "; "))));
      return out + "\\end{itemize}\n";
  }
  return out;
}

nlohmann::ordered_json parameter_box_json(const Model& m) {
  nlohmann::ordered_json j = nlohmann::ordered_json::array();
  for (const auto& p : m.free_params()) {
    const Interval b = m.box(p);
    j.push_back({{"name", p.get_name()}, {"lo", to_string(b.lo)}, {"hi", to_string(b.hi)}});
  }
  return j;
}

namespace {

// The box of the free parameters on which the verdicts hold (symbolic in them).
std::string parameter_box_text(const Model& m, ReportFormat format) {
  if (m.free_params().empty()) return "";
  std::vector<std::string> boxes;
  for (const auto& p : m.free_params()) {
    const Interval b = m.box(p);
    boxes.push_back(fmt::format("{} in [{}, {}]", p.get_name(), to_string(b.lo), to_string(b.hi)));
  }
  const std::string text = fmt::format(
      "Free parameters {}: the analysis is symbolic in them and its verdicts hold on this box; "
      "generated observers take them as run-time parameters (--param binds them)",
      fmt::join(boxes, ", "));
  switch (format) {
    case ReportFormat::markdown:
      return "\n## Parameters\n\n" + text + ".\n";
    case ReportFormat::latex:
      return "\n\\subsection*{Parameters}\n" + latex_text(text) + ".\n";
    default:
      return "\nParameters\n  " + text + ".\n";
  }
}

}  // namespace

std::string render_check(const Analysis& a, ReportFormat format, const ReportOptions& opt,
                         const nlohmann::ordered_json& verdicts) {
  if (format == ReportFormat::json) {
    auto j = report_json(a, opt);
    j["parameters"] = parameter_box_json(a.model);
    j["designs"] = verdicts;
    return j.dump(2) + "\n";
  }
  return render_report(a, format, opt) + parameter_box_text(a.model, format) +
         render_design_verdicts(verdicts, format);
}

nlohmann::ordered_json generated_json(const std::vector<GeneratedObserver>& g) {
  nlohmann::ordered_json j = nlohmann::ordered_json::array();
  for (const auto& o : g) {
    nlohmann::ordered_json rows = nlohmann::ordered_json::object();
    for (const auto& r : o.rows) rows[r.key] = r.value;
    nlohmann::ordered_json params = nlohmann::ordered_json::array();
    for (const auto& p : o.params)
      params.push_back({{"name", p.name},
                        {"default", to_string(p.default_value)},
                        {"default_reason", p.default_reason}});
    j.push_back({{"method", o.method},
                 {"file", o.file},
                 {"class", o.class_name},
                 {"summary", o.summary},
                 {"design", rows},
                 {"runtime_parameters", params},
                 {"usage_example", o.usage_example}});
  }
  return j;
}

std::string render_generated_markdown(const std::vector<GeneratedObserver>& g) {
  std::string md;
  for (const auto& o : g) {
    md += fmt::format("\n### `{}`: `{}`\n\n{}\n\n", o.method, o.class_name, o.summary);
    md += "| design | value |\n|---|---|\n";
    for (const auto& r : o.rows) md += fmt::format("| {} | {} |\n", r.key, r.value);
    if (!o.params.empty()) {
      md += o.c_language ? "\nRun-time parameters (fields of the observer's `prm` member):\n\n"
                         : "\nRun-time parameters (`Params`, set with `set_params()`):\n\n";
      for (const auto& p : o.params)
        md += fmt::format("- `{}`: default {} ({})\n", p.name, to_string(p.default_value),
                          p.default_reason);
    }
    md += fmt::format("\nUsage:\n\n```{}\n{}```\n", o.c_language ? "c" : "cpp", o.usage_example);
  }
  return md;
}

}  // namespace obsynth
