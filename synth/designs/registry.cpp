#include "designs/registry.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <stdexcept>

#include "symbolic/expr_print.hpp"

#include "designs/canonical.hpp"
#include "designs/extended_linearization.hpp"
#include "designs/finite_time.hpp"
#include "designs/high_gain.hpp"
#include "designs/kalman_theta.hpp"
#include "designs/kou.hpp"
#include "designs/perfect.hpp"
#include "designs/riccati.hpp"
#include "designs/thau.hpp"

namespace obsynth {

const char* guarantee_name(Guarantee g) {
  switch (g) {
    case Guarantee::rigorous:
      return "rigorous";
    case Guarantee::partial:
      return "partial";
    case Guarantee::none:
      break;
  }
  return "none";
}

std::string Verdict::text() const {
  return fmt::format("{}", fmt::join(reasons, "; "));
}

namespace {

bool undefined_in_box(const Analysis& a, Verdict& v) {
  if (!a.definedness.undefined_somewhere()) return false;
  std::vector<std::string> where;
  for (const auto& f : a.definedness.findings)
    if (f.status != certify::DefinedStatus::not_excluded) where.push_back(f.short_text());
  v.reasons.push_back(fmt::format(
      "the model is undefined inside the domain box, where this design's guarantee and its "
      "generated code evaluate it ({}; shrink the box to exclude it)",
      fmt::join(where, "; ")));
  return true;
}

// A rigorous guarantee over the box needs the model defined on all of it: when a condition could
// not be proved (nor a failure), the guarantee is partial and says which.
void downgrade_unproved_definedness(const Analysis& a, Verdict& v) {
  if (a.definedness.findings.empty() || !v.applies) return;
  v.reasons.push_back("note: " + a.definedness.summary());
  if (v.guarantee != Guarantee::rigorous) return;
  v.guarantee = Guarantee::partial;
  v.guarantee_text += "; only where the model is defined: " + a.definedness.summary();
}

}  // namespace

Verdict design_verdict(const Design& d, Plan& plan, const Analysis& a, bool assess) {
  const Model& m = a.model;
  Verdict v;
  if (d.max_outputs != 0 && m.p() > d.max_outputs) {
    v.reasons.push_back(fmt::format("the design handles {} output{}; the model has p = {}{}",
                                    d.max_outputs, d.max_outputs == 1 ? "" : "s", m.p(),
                                    d.outputs_note.empty() ? "" : ": " + d.outputs_note));
    return v;
  }
  if (!m.output_offset.empty() && !d.observes_output_offset) {
    v.reasons.push_back(fmt::format(
        "the output has a direct feedthrough k(u) = [{}]; this design feeds y itself to its "
        "filters or differentiators and cannot observe y - k(u)",
        fmt::join(to_strings(m.output_offset), ", ")));
    return v;
  }
  if (m.feedthrough() && !d.accepts_feedthrough) {
    v.reasons.push_back(
        "the output depends on the input in a way that does not split as h0(x) + k(u) "
        "(direct feedthrough y = h(x, u)); this design needs y = h(x)");
    return v;
  }
  // Every design's guarantee holds on the domain box, and its generated code evaluates the model
  // there: a model proved undefined somewhere in the box (a pole of f, sqrt of a negative) gets
  // no design, with the place named.
  if (undefined_in_box(a, v)) return v;
  // A design that evaluates the model where it is undefined (the expansion point on a pole)
  // does not apply there: GiNaC's division by zero is a verdict, never an internal error.
  try {
    v = plan.verdict();
    if (v.applies) {
      if (assess)
        plan.assess(v);
      else if (d.has_assessment)
        v.guarantee_text = "not assessed (its certificate runs with `obsynth check --certify`)";
    }
    downgrade_unproved_definedness(a, v);
  } catch (const std::domain_error& e) {  // GiNaC::pole_error derives from it
    v = Verdict{};
    v.reasons.push_back(fmt::format(
        "{}: the model is undefined where this design evaluates it ({}): f, g or h has a "
        "singularity in the domain box (shrink the box to exclude it)",
        d.name, e.what()));
  }
  return v;
}

Verdict design_verdict(const Design& d, const Analysis& a, bool assess) {
  const std::unique_ptr<Plan> plan = d.plan(a, DesignOptions{});
  return design_verdict(d, *plan, a, assess);
}

Plan& PlanSet::plan(const Design& d) {
  std::unique_ptr<Plan>& p = plans_[d.name];
  if (!p) p = d.plan(a_, options_for(d, options_));
  return *p;
}

const Verdict& PlanSet::verdict(const Design& d, bool assess) {
  const auto key = std::make_pair(d.name, assess);
  auto it = verdicts_.find(key);
  if (it == verdicts_.end())
    it = verdicts_.emplace(key, design_verdict(d, plan(d), a_, assess)).first;
  return it->second;
}

ObserverSpec PlanSet::build(const Design& d) {
  ObserverSpec s = plan(d).build();
  // A build may sharpen the verdict (finite-time's guarantee comes with its tables).
  verdicts_.erase({d.name, false});
  verdicts_.erase({d.name, true});
  return s;
}

const std::vector<Design>& design_registry() {
  static const std::vector<Design> designs = {
      canonical_design(),    perfect_design(), high_gain_design(), riccati_design(),
      kalman_theta_design(), thau_design(),    kou_design(),       extended_linearization_design(),
      finite_time_design(),
  };
  return designs;
}

const std::vector<std::string>& planned_methods() {
  static const std::vector<std::string> planned = {};
  return planned;
}

const Design* find_design(const std::string& name) {
  for (const auto& d : design_registry())
    if (d.name == name) return &d;
  return nullptr;
}

std::string persistent_input_designs(const ObservabilityUnderInputs& u) {
  // The designs with a further condition (uniform observability) come last.
  std::vector<std::string> out;
  for (const bool conditional : {false, true})
    for (const auto& d : design_registry()) {
      if (!d.observes_along_inputs || d.needs_uniform_observability != conditional) continue;
      if (conditional && u.uniformly_observable == false) continue;
      out.push_back(d.along_inputs_note.empty()
                        ? d.name
                        : fmt::format("{} ({})", d.name, d.along_inputs_note));
    }
  return fmt::format("{}", fmt::join(out, ", "));
}

std::string qualified_option_name(const Design& d, const std::string& option) {
  return d.name + "." + option;
}

DesignOptions options_for(const Design& d, const DesignOptions& given) {
  DesignOptions own;
  for (const auto& o : d.options) {
    const std::string* v = given.find(qualified_option_name(d, o.name));
    if (!v || v->empty()) v = given.find(o.name);
    if (v && !v->empty()) own.values[o.name] = *v;
  }
  return own;
}

std::vector<DesignOptionInfo> all_design_options() {
  std::vector<DesignOptionInfo> out;
  for (const auto& d : design_registry())
    for (const auto& o : d.options)
      if (std::none_of(out.begin(), out.end(), [&](const auto& q) { return q.name == o.name; }))
        out.push_back(o);
  for (const auto& d : design_registry())
    for (const auto& o : d.options)
      out.push_back({qualified_option_name(d, o.name), o.help + " (for " + d.name + " alone)",
                     o.default_text});
  return out;
}

}  // namespace obsynth
