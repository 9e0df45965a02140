#include "app/synthesize.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cstdio>

#include "app/design_report.hpp"
#include "app/report.hpp"
#include "app/worker.hpp"
#include "designs/registry.hpp"
#include "emit/emit_c.hpp"
#include "symbolic/expr_print.hpp"

namespace obsynth {

namespace {

std::string known_methods() {
  std::vector<std::string> names;
  for (const auto& d : design_registry()) names.push_back(d.name);
  for (const auto& p : planned_methods()) names.push_back(p);
  return fmt::format("{}", fmt::join(names, ", "));
}

std::string implemented_methods() {
  std::vector<std::string> names;
  for (const auto& d : design_registry()) names.push_back(d.name);
  return fmt::format("{}", fmt::join(names, ", "));
}

// "Not observable" only when no input makes the model observable (issue 8).
std::string not_observable_note(const Analysis& a) {
  const ObservabilityUnderInputs& ui = a.under_inputs;
  if (a.observability.generic_rank >= a.model.n()) return "";
  if (ui.computed && ui.observable_for_some_input == false)
    return fmt::format(
        "; the model is not observable for any input ({}): no observer can reconstruct the whole "
        "state; reduce the model to its observable part",
        ui.reason);
  if (ui.computed && ui.observable_for_some_input == true)
    return fmt::format(
        "; the drift alone (u = {}) has rank {} < n = {}, but the model is observable under "
        "inputs (rank O_u = {}; {}): designs that work under persistent inputs: {}",
        a.model.nominal.empty() ? "0" : "u0", a.observability.generic_rank, a.model.n(),
        ui.generic_rank, ui.reason, persistent_input_designs(ui));
  return fmt::format("; the drift alone has rank {} < n = {}; observability under inputs: {}",
                     a.observability.generic_rank, a.model.n(),
                     ui.reason.empty() ? "not computed" : ui.reason);
}

// One design auto may take: its verdict and registry position (its cost rank).
struct Candidate {
  const Design* design;
  Verdict verdict;
  std::size_t order;
};

// Stronger guarantee first, then cheaper (registry order).
bool ranks_before(const Candidate& a, const Candidate& b) {
  if (a.verdict.guarantee != b.verdict.guarantee) return a.verdict.guarantee > b.verdict.guarantee;
  return a.order < b.order;
}

std::string guarantee_line(const Verdict& v) {
  const std::string name = guarantee_name(v.guarantee);
  if (v.guarantee_text.empty() || v.guarantee_text.rfind(name, 0) == 0)
    return v.guarantee_text.empty() ? name : v.guarantee_text;
  return fmt::format("{}: {}", name, v.guarantee_text);
}

std::string auto_explanation(const Candidate& best, const std::vector<Candidate>& others,
                             const std::vector<std::string>& rejected) {
  std::string text = fmt::format("auto: chose '{}' (guarantee {}) because {}", best.design->name,
                                 guarantee_line(best.verdict), best.verdict.text());
  std::vector<std::string> ranked;
  for (const auto& c : others)
    ranked.push_back(fmt::format("{} (guarantee {})", c.design->name, guarantee_line(c.verdict)));
  if (!ranked.empty())
    text += fmt::format(" (also applies, ranked below it: {})", fmt::join(ranked, "; "));
  if (!rejected.empty()) text += fmt::format(" (rejected: {})", fmt::join(rejected, "; "));
  return text;
}

// auto ranks the designs that apply by the guarantee their own certificate gives on this model
// (rigorous over the domain > on a sub-box or sampled > none), then by cost (registry order).
std::string choose_auto(const Analysis& a, std::string& explanation,
                        const std::vector<ExcludedDesign>& excluded) {
  std::vector<std::string> rejected;
  std::vector<Candidate> applying;
  const auto& registry = design_registry();
  for (std::size_t i = 0; i < registry.size(); ++i) {
    const Design& d = registry[i];
    if (!d.in_all) continue;  // by name only (large tables)
    const auto skip = std::find_if(excluded.begin(), excluded.end(),
                                   [&](const ExcludedDesign& e) { return e.method == d.name; });
    if (skip != excluded.end()) {
      rejected.push_back(fmt::format("{}: it applies, but its build {}", d.name, skip->reason));
      continue;
    }
    Verdict v = design_verdict(d, a);
    if (v.applies)
      applying.push_back({&d, std::move(v), i});
    else
      rejected.push_back(fmt::format("{}: {}", d.name, v.text()));
  }
  if (!applying.empty()) {
    std::stable_sort(applying.begin(), applying.end(), ranks_before);
    explanation = auto_explanation(
        applying.front(), std::vector<Candidate>(applying.begin() + 1, applying.end()), rejected);
    return applying.front().design->name;
  }
  throw UserError(
      SourceLoc{a.model.file, 0, 0},
      fmt::format("no implemented observer design applies to model '{}': {}{}; not implemented "
                  "yet: {}",
                  a.model.name, fmt::join(rejected, "; "), not_observable_note(a),
                  fmt::join(planned_methods(), ", ")));
}

}  // namespace

std::vector<std::string> resolve_methods(const Analysis& a, const std::vector<std::string>& asked,
                                         std::string& explanation,
                                         const std::vector<ExcludedDesign>& excluded,
                                         std::string* auto_choice) {
  std::vector<std::string> methods;
  for (const auto& m : asked) {
    std::string name = m;
    if (m == "all") {
      for (const auto& d : design_registry())
        if (d.in_all && design_verdict(d, a).applies &&
            std::find(methods.begin(), methods.end(), d.name) == methods.end())
          methods.push_back(d.name);
      continue;
    }
    if (m == "auto") {
      name = choose_auto(a, explanation, excluded);
      if (auto_choice) *auto_choice = name;
    } else if (!find_design(m)) {
      const auto& planned = planned_methods();
      if (std::find(planned.begin(), planned.end(), m) != planned.end())
        throw UserError(SourceLoc{}, fmt::format("method '{}' is not implemented in this version "
                                                 "of obsynth (implemented: {})",
                                                 m, implemented_methods()));
      throw UserError(SourceLoc{}, fmt::format("unknown method '{}' (known: auto, all, {})", m,
                                               known_methods()));
    }
    if (std::find(methods.begin(), methods.end(), name) == methods.end()) methods.push_back(name);
  }
  return methods;
}

DesignOptions with_model_options(const Model& m, const DesignOptions& given) {
  DesignOptions out = given;
  const auto known = all_design_options();
  for (const auto& opt : m.options) {
    const bool declared = std::any_of(
        known.begin(), known.end(), [&](const DesignOptionInfo& i) { return i.name == opt.name; });
    if (!declared) {
      std::vector<std::string> names;
      for (const auto& i : known) names.push_back(i.name);
      throw UserError(opt.loc, fmt::format("option '{}' is not a parameter of any registered "
                                           "design (known: {})",
                                           opt.name, fmt::join(names, ", ")));
    }
    out.values.emplace(opt.name, opt.value);  // a command-line value, already there, wins
  }
  return out;
}

namespace {

// y -> y - k(u) in every generated function that reads y (Model::output_offset).
void observe_output_offset(ObserverSpec& s, const Model& m) {
  for (auto& f : s.functions) {
    GiNaC::exmap shift;
    bool reads_u = false;
    for (const auto& arg : f.args) {
      reads_u = reads_u || arg.kind == FunctionArg::Kind::input;
      if (arg.kind != FunctionArg::Kind::output) continue;
      for (std::size_t i = 0; i < arg.symbols.size() && i < m.output_offset.size(); ++i)
        shift[arg.symbols[i]] = arg.symbols[i] - m.output_offset[i];
    }
    if (shift.empty()) continue;
    if (!reads_u)
      throw UserError(SourceLoc{m.file, 0, 0},
                      fmt::format("method '{}' cannot observe y - k(u) (direct feedthrough): its "
                                  "function '{}' reads y but not u",
                                  s.method, f.name));
    for (auto& l : f.lets) l.value = l.value.subs(shift);
    for (auto& e : f.outputs) e = e.subs(shift);
    if (!f.doc.empty()) f.doc += " y enters as y - k(u) (direct feedthrough).";
  }
  s.report.push_back({"direct feedthrough",
                      fmt::format("y = h0(x) + k(u) with k(u) = [{}]: the observer reads y - k(u)",
                                  fmt::join(to_strings(m.output_offset), ", "))});
}

}  // namespace

ObserverSpec build_design(const Analysis& a, const std::string& method, const DesignOptions& o) {
  const Design* d = find_design(method);
  OBSYNTH_ASSERT(d != nullptr, "build_design: unresolved method " + method);
  if (!d->observes_output_offset || (a.model.feedthrough() && !d->accepts_feedthrough)) {
    const Verdict v = design_verdict(*d, a);
    if (!v.applies)
      throw UserError(SourceLoc{a.model.file, 0, 0},
                      fmt::format("method '{}' does not apply: {}", method, v.text()));
  }
  ObserverSpec s = d->build(a, with_model_options(a.model, o));
  if (!a.model.output_offset.empty()) observe_output_offset(s, a.model);
  return s;
}

namespace {

// The chosen methods' specs. When a budget stops the build of the design auto chose (within
// this process; main.cpp reruns after a worker's time or memory stop), auto passes over it and
// chooses again, with a note on stderr. Other errors (a bad option value) still end the job.
std::vector<std::pair<std::string, ObserverSpec>> build_chosen(
    const Analysis& a, const SynthesisOptions& opt, std::vector<ExcludedDesign>& excluded,
    std::vector<std::string>& chosen, std::string& explanation) {
  for (;;) {
    std::string auto_choice;
    chosen = resolve_methods(a, opt.methods, explanation, excluded, &auto_choice);
    std::vector<std::pair<std::string, ObserverSpec>> specs;
    std::string failed, why;
    for (const auto& method : chosen) {
      publish_stage(method + " design");
      try {
        specs.emplace_back(method, build_design(a, method, opt.design));
      } catch (const BudgetExceeded& e) {
        if (method != auto_choice) throw;
        why = fmt::format("stopped: stage '{}' {}", e.stage(), e.reason());
      }
      if (!why.empty()) {
        failed = method;
        break;
      }
    }
    if (failed.empty()) return specs;
    std::fprintf(stderr,
                 "obsynth: note: auto chose '%s', but its build %s; auto tries the next design\n",
                 failed.c_str(), why.c_str());
    excluded.push_back({failed, why});
  }
}

// An observer whose own certificate proves nothing on this model is never emitted silently.
std::vector<std::string> guarantee_warnings(const Analysis& a,
                                            const std::vector<std::string>& chosen) {
  std::vector<std::string> out;
  for (const auto& method : chosen) {
    const Verdict v = design_verdict(*find_design(method), a);
    if (v.guarantee != Guarantee::none) continue;
    out.push_back(fmt::format(
        "the '{}' observer carries no convergence guarantee for this model{}; check it in "
        "simulation (obsynth simulate) before you use it",
        method, v.guarantee_text.empty() ? "" : ": " + v.guarantee_text));
  }
  return out;
}

}  // namespace

Synthesis synthesize(const Analysis& a, const SynthesisOptions& opt) {
  Synthesis s;
  with_model_options(a.model, opt.design);  // unknown option lines fail before any work
  const bool auto_asked =
      std::find(opt.methods.begin(), opt.methods.end(), "auto") != opt.methods.end();
  // Each step under its own stage name, so that a budget stop names it (worker watchdog).
  publish_stage("verdicts");
  std::vector<ExcludedDesign> excluded = opt.auto_excluded;
  const std::vector<std::pair<std::string, ObserverSpec>> specs =
      build_chosen(a, opt, excluded, s.chosen, s.explanation);
  s.warnings = guarantee_warnings(a, s.chosen);
  for (const auto& spec : specs) s.warnings.insert(s.warnings.end(), spec.second.warnings.begin(),
                                                   spec.second.warnings.end());
  std::vector<GeneratedObserver> generated;
  for (const auto& [method, spec] : specs) {
    const bool c = opt.emit.language == Language::c;
    const EmittedHeader h = c ? emit_c_pair(a, spec, opt.emit) : emit_cxx_header(a, spec, opt.emit);
    s.files.push_back({h.filename, h.text});
    if (c) s.files.push_back({h.source_filename, h.source_text});
    // C has no namespaces: its observer is the struct type <model>_<method>_observer.
    const std::string type =
        c ? h.class_name : fmt::format("obsynth_gen::{}::{}", h.namespace_name, h.class_name);
    generated.push_back({method, h.filename, type,
                         fmt::format("`{}`: {} `{}`, {} arithmetic operations in its functions.",
                                     h.filename, spec.summary, type, h.operations),
                         h.usage_example, c, spec.report, spec.params});
    if (auto_asked && !c && method == s.chosen.front()) {
      const EmittedHeader alias = emit_cxx_auto_alias(a, h, method);
      s.files.push_back({alias.filename, alias.text});
    }
  }
  ReportOptions ro;
  ro.timings = false;  // the output directory is byte-identical between runs
  // Named methods only: their verdicts (the others' searches cost seconds); auto and all: every
  // one.
  const bool every =
      auto_asked || std::find(opt.methods.begin(), opt.methods.end(), "all") != opt.methods.end();
  VerdictScope scope;
  if (!every) scope.only = s.chosen;
  publish_stage("report");
  const auto verdicts = design_verdicts_json(a, scope);
  std::string md;
  for (const auto& w : s.warnings) md += "> **Warning:** " + w + "\n\n";
  md += render_check(a, ReportFormat::markdown, ro, verdicts);
  md += "\n## Generated observers\n\n";
  if (!s.explanation.empty()) md += s.explanation + ".\n\n";
  for (const auto& g : generated) md += "- " + g.summary + "\n";
  md += opt.emit.language == Language::c
            ? fmt::format("\nC99 pairs (.h and .c); scalar type and literals are {}.\n",
                          precision_name(opt.emit.precision))
            : fmt::format(
                  "\nLiterals are {} precision; every class is a template on the scalar type "
                  "(float and double).\n",
                  precision_name(opt.emit.precision));
  md += render_generated_markdown(generated);
  auto j = report_json(a, ro);
  j["parameters"] = parameter_box_json(a.model);
  j["designs"] = verdicts;
  if (!s.explanation.empty()) j["auto"] = s.explanation;
  if (!s.warnings.empty()) j["warnings"] = s.warnings;
  j["generated"] = generated_json(generated);
  const std::string stem = cxx_identifier(a.model.name);
  s.files.push_back({stem + "_report.md", md});
  s.files.push_back({stem + "_report.json", j.dump(2) + "\n"});
  return s;
}

}  // namespace obsynth
