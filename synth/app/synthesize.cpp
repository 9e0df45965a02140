#include "app/synthesize.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cstdio>
#include <optional>
#include <stdexcept>

#include "app/design_report.hpp"
#include "app/report.hpp"
#include "app/simulate.hpp"
#include "app/stages.hpp"
#include "app/trial.hpp"
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
std::string choose_auto(PlanSet& plans, std::string& explanation,
                        const std::vector<ExcludedDesign>& excluded, Guarantee* guarantee) {
  const Analysis& a = plans.analysis();
  std::vector<std::string> rejected;
  std::vector<Candidate> applying;
  const auto& registry = design_registry();
  for (std::size_t i = 0; i < registry.size(); ++i) {
    const Design& d = registry[i];
    if (!d.in_all) continue;  // by name only (large tables)
    const auto skip = std::find_if(excluded.begin(), excluded.end(),
                                   [&](const ExcludedDesign& e) { return e.method == d.name; });
    if (skip != excluded.end()) {
      rejected.push_back(fmt::format("{}: {}", d.name, skip->reason));
      continue;
    }
    // Its own stage: a budget stop in one design's certificate search passes over that design
    // (main.cpp), as a stop in its build does.
    publish_stage(design_stage_name(d.name, DesignStage::verdict));
    const Verdict& v = plans.verdict(d);
    if (v.applies)
      applying.push_back({&d, v, i});
    else
      rejected.push_back(fmt::format("{}: {}", d.name, v.text()));
  }
  if (!applying.empty()) {
    std::stable_sort(applying.begin(), applying.end(), ranks_before);
    explanation = auto_explanation(
        applying.front(), std::vector<Candidate>(applying.begin() + 1, applying.end()), rejected);
    if (guarantee) *guarantee = applying.front().verdict.guarantee;
    return applying.front().design->name;
  }
  // The model's own definedness findings come first, at their place in the file.
  std::vector<Diagnostic> diags;
  for (const auto& f : a.definedness.findings)
    if (f.status != certify::DefinedStatus::not_excluded)
      diags.push_back({Severity::error, f.loc, f.text()});
  const std::string planned =
      planned_methods().empty()
          ? std::string()
          : fmt::format("; not implemented yet: {}", fmt::join(planned_methods(), ", "));
  diags.push_back(
      {Severity::error, SourceLoc{a.model.file, 0, 0},
       fmt::format("no implemented observer design applies to model '{}': {}{}{}", a.model.name,
                   fmt::join(rejected, "; "), not_observable_note(a), planned)});
  throw UserError(std::move(diags));
}

}  // namespace

std::vector<std::string> resolve_methods(const Analysis& a, const std::vector<std::string>& asked,
                                         std::string& explanation,
                                         const std::vector<ExcludedDesign>& excluded,
                                         std::string* auto_choice, Guarantee* auto_guarantee) {
  PlanSet plans(a, with_model_options(a.model, DesignOptions{}));
  return resolve_methods(plans, asked, explanation, excluded, auto_choice, auto_guarantee);
}

std::vector<std::string> resolve_methods(PlanSet& plans, const std::vector<std::string>& asked,
                                         std::string& explanation,
                                         const std::vector<ExcludedDesign>& excluded,
                                         std::string* auto_choice, Guarantee* auto_guarantee) {
  std::vector<std::string> methods;
  for (const auto& m : asked) {
    std::string name = m;
    if (m == "all") {
      for (const auto& d : design_registry())
        if (d.in_all && plans.verdict(d).applies &&
            std::find(methods.begin(), methods.end(), d.name) == methods.end())
          methods.push_back(d.name);
      continue;
    }
    if (m == "auto") {
      name = choose_auto(plans, explanation, excluded, auto_guarantee);
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
  // `all` with no design that applies: the main job writes no observer, so it fails as `auto`
  // does, with every design's reason.
  if (methods.empty()) choose_auto(plans, explanation, excluded, nullptr);
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

namespace {

// Every discretised design reports its largest safe sample period: the designs whose step has
// its own scheme (exact, sub-stepped, solved) compute it themselves; for the other ODE
// observers it is sampled here from the spec (app/simulate.hpp sampled_safe_period).
void add_safe_period_row(const Analysis& a, ObserverSpec& s) {
  const std::string key = "largest safe sample period";
  for (const auto& row : s.report)
    if (row.key == key) return;
  const auto safe = sampled_safe_period(a, s);
  if (!safe) return;
  s.report.push_back(
      {key, fmt::format("{:.3g} (sampled, not a proof: RK4's stability radius {} over the largest "
                        "|eigenvalue| {:.4g} of d(rhs)/dw at {} points of the domain box, on the "
                        "trajectory; a longer period can make the discrete observer unstable)",
                        safe->period, kRk4StabilityRadius, safe->rho, safe->samples)});
}

}  // namespace

ObserverSpec build_design(const Analysis& a, const std::string& method, const DesignOptions& o) {
  PlanSet plans(a, with_model_options(a.model, o));
  return build_design(plans, method);
}

ObserverSpec build_design(PlanSet& plans, const std::string& method) {
  const Analysis& a = plans.analysis();
  const Design* d = find_design(method);
  OBSYNTH_ASSERT(d != nullptr, "build_design: unresolved method " + method);
  if (!d->observes_output_offset || (a.model.feedthrough() && !d->accepts_feedthrough)) {
    const Verdict& v = plans.verdict(*d);
    if (!v.applies)
      throw UserError(SourceLoc{a.model.file, 0, 0},
                      fmt::format("method '{}' does not apply: {}", method, v.text()));
  }
  ObserverSpec s;
  try {
    s = plans.build(*d);
  } catch (const std::domain_error& e) {  // GiNaC's division by zero (pole_error derives from it)
    throw UserError(SourceLoc{a.model.file, 0, 0},
                    fmt::format("method '{}': the model is undefined where the design evaluates "
                                "it ({}): f, g or h has a singularity in the domain box (shrink "
                                "the box to exclude it)",
                                method, e.what()));
  }
  if (!a.model.output_offset.empty()) observe_output_offset(s, a.model);
  add_safe_period_row(a, s);
  return s;
}

namespace {

using BuiltSpecs = std::vector<std::pair<std::string, ObserverSpec>>;

// A choice auto passed over for its closed-loop trial, kept in case nothing better comes.
struct TrialFallback {
  std::vector<std::string> chosen;
  std::string explanation, warning;
  BuiltSpecs specs;
  Guarantee guarantee = Guarantee::none;
};

// auto's closed-loop trials (app/trial.hpp): the first design that converges in its trial is
// taken. A design whose error fell too slowly is passed over only for one of the same guarantee
// that converges; one that failed (rejected its step, diverged, left the box) is passed over for
// any other. When nothing converges, the slow design ranked first is taken, else the failed one,
// with a warning.
class TrialChoice {
 public:
  TrialChoice(const Analysis& a, std::vector<ExcludedDesign>& excluded)
      : a_(a), excluded_(excluded) {}

  // True when this choice is taken; false when auto tries the next design.
  bool accept(const std::string& method, const ObserverSpec& spec, TrialFallback attempt,
              std::string& explanation) {
    publish_stage(design_stage_name(method, DesignStage::trial));
    const TrialOutcome trial = closed_loop_trial(a_, spec);
    const std::string found = fmt::format("{}: {}", trial.setup, trial.text);
    if (trial.verdict == TrialVerdict::passed || trial.verdict == TrialVerdict::inconclusive) {
      explanation += fmt::format(
          "; its {}{}", found,
          trial.verdict == TrialVerdict::inconclusive ? " (inconclusive about the observer)" : "");
      return true;
    }
    std::fprintf(stderr, "obsynth: note: auto chose '%s', but its %s; auto tries the next design\n",
                 method.c_str(), found.c_str());
    excluded_.push_back({method, "it applies, but its " + found});
    attempt.explanation += "; its " + found;
    std::optional<TrialFallback>& keep = trial.verdict == TrialVerdict::slow ? slow_ : failed_;
    if (!keep) {
      keep = std::move(attempt);
      keep->warning = fmt::format(
          "auto's closed-loop trial of '{0}' did not converge ({1}); '{0}' is emitted all the "
          "same, as the best-ranked design that is left: check it in simulation with your "
          "inputs",
          method, found);
    }
    return false;
  }
  std::optional<TrialFallback> fallback() const { return slow_ ? slow_ : failed_; }
  // A slow design is taken before any design of a weaker guarantee is tried.
  const TrialFallback* slow_above(Guarantee g) const {
    return slow_ && slow_->guarantee > g ? &*slow_ : nullptr;
  }

 private:
  const Analysis& a_;
  std::vector<ExcludedDesign>& excluded_;
  std::optional<TrialFallback> slow_, failed_;
};

BuiltSpecs take_fallback(const TrialFallback& f, std::vector<std::string>& chosen,
                         std::string& explanation, std::vector<std::string>& warnings) {
  chosen = f.chosen;
  explanation = f.explanation;
  warnings.push_back(f.warning);
  return f.specs;
}

// The chosen methods' specs. When a budget stops the build of the design auto chose (within
// this process; main.cpp reruns after a worker's time or memory stop), or its closed-loop
// trial does not converge (TrialChoice), auto passes over it and chooses again, with a note on
// stderr. Other errors (a bad option value) still end the job.
BuiltSpecs build_chosen(PlanSet& plans, const SynthesisOptions& opt,
                        std::vector<ExcludedDesign>& excluded, std::vector<std::string>& chosen,
                        std::string& explanation, std::vector<std::string>& warnings) {
  TrialChoice trials(plans.analysis(), excluded);
  for (;;) {
    std::string auto_choice;
    Guarantee guarantee = Guarantee::none;
    try {
      chosen = resolve_methods(plans, opt.methods, explanation, excluded, &auto_choice, &guarantee);
    } catch (const UserError&) {
      const auto f = trials.fallback();
      if (!f) throw;
      return take_fallback(*f, chosen, explanation, warnings);
    }
    if (const TrialFallback* slow = trials.slow_above(guarantee))
      return take_fallback(*slow, chosen, explanation, warnings);
    BuiltSpecs specs;
    std::string failed, why;
    for (const auto& method : chosen) {
      publish_stage(design_stage_name(method, DesignStage::design));
      try {
        specs.emplace_back(method, build_design(plans, method));
      } catch (const BudgetExceeded& e) {
        if (method != auto_choice) throw;
        why = fmt::format("{}stage '{}' {}", passed_over_clause(DesignStage::design), e.stage(),
                          e.reason());
      }
      if (!why.empty()) {
        failed = method;
        break;
      }
    }
    if (failed.empty()) {
      const auto it = std::find_if(specs.begin(), specs.end(),
                                   [&](const auto& s) { return s.first == auto_choice; });
      if (it == specs.end() ||
          trials.accept(auto_choice, it->second,
                        TrialFallback{chosen, explanation, "", specs, guarantee}, explanation))
        return specs;
      continue;
    }
    std::fprintf(stderr, "obsynth: note: auto chose '%s', but %s; auto tries the next design\n",
                 failed.c_str(), why.substr(std::string("it applies, but ").size()).c_str());
    excluded.push_back({failed, why});
  }
}

// An observer whose own certificate proves nothing on this model is never emitted silently.
std::vector<std::string> guarantee_warnings(PlanSet& plans,
                                            const std::vector<std::string>& chosen) {
  std::vector<std::string> out;
  for (const auto& method : chosen) {
    const Verdict& v = plans.verdict(*find_design(method));
    if (v.guarantee != Guarantee::none) continue;
    out.push_back(fmt::format(
        "the '{}' observer carries no convergence guarantee for this model{}; check it in "
        "simulation (obsynth simulate) before you use it",
        method, v.guarantee_text.empty() ? "" : ": " + v.guarantee_text));
  }
  return out;
}

}  // namespace

BuiltDesign choose_and_build(const Analysis& a, const std::string& method,
                             const DesignOptions& design, std::string& explanation) {
  SynthesisOptions opt;
  opt.methods = {method};
  opt.design = design;
  std::vector<ExcludedDesign> excluded;
  std::vector<std::string> chosen, warnings;
  PlanSet plans(a, with_model_options(a.model, design));
  BuiltSpecs specs = build_chosen(plans, opt, excluded, chosen, explanation, warnings);
  OBSYNTH_ASSERT(specs.size() == 1, "choose_and_build: one method gives one observer");
  return {specs.front().first, std::move(specs.front().second)};
}

namespace {

// The header (and C source) of one design; an emission error (a constant the precision cannot
// represent) names the model file and the design.
EmittedHeader emit_for(const Analysis& a, const std::string& method, const ObserverSpec& spec,
                       const EmitOptions& opt) {
  try {
    return opt.language == Language::c ? emit_c_pair(a, spec, opt) : emit_cxx_header(a, spec, opt);
  } catch (const UserError& e) {
    std::vector<Diagnostic> diags = e.diagnostics();
    for (auto& d : diags) {
      if (d.loc.file.empty()) d.loc.file = a.model.file;
      d.message = fmt::format("the '{}' observer: {}", method, d.message);
    }
    throw UserError(std::move(diags));
  }
}

}  // namespace

Synthesis synthesize(const Analysis& a, const SynthesisOptions& opt) {
  Synthesis s;
  // Unknown option lines fail before any work; every design's plan reads the merged options.
  PlanSet plans(a, with_model_options(a.model, opt.design));
  const bool auto_asked =
      std::find(opt.methods.begin(), opt.methods.end(), "auto") != opt.methods.end();
  // Each step under its own stage name, so that a budget stop names it (worker watchdog).
  publish_stage("verdicts");
  std::vector<ExcludedDesign> excluded = opt.auto_excluded;
  std::vector<std::string> trial_warnings;
  const BuiltSpecs specs =
      build_chosen(plans, opt, excluded, s.chosen, s.explanation, trial_warnings);
  s.warnings = guarantee_warnings(plans, s.chosen);
  s.warnings.insert(s.warnings.end(), trial_warnings.begin(), trial_warnings.end());
  for (const auto& spec : specs)
    s.warnings.insert(s.warnings.end(), spec.second.warnings.begin(), spec.second.warnings.end());
  std::vector<GeneratedObserver> generated;
  for (const auto& [method, spec] : specs) {
    const bool c = opt.emit.language == Language::c;
    const EmittedHeader h = emit_for(a, method, spec, opt.emit);
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
  for (const auto& e : excluded)
    if (verdict_stopped(e)) scope.passed_over[e.method] = e.reason;
  publish_stage("report");
  const auto verdicts = design_verdicts_json(plans, scope);
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
