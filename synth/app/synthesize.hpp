// The main job as a pure function: analysis -> chosen designs (registry) -> ObserverSpecs ->
// header texts and reports.
#pragma once

#include <string>
#include <vector>

#include "analysis/analysis.hpp"
#include "app/output_dir.hpp"
#include "designs/registry.hpp"
#include "designs/spec.hpp"
#include "emit/emit_cxx.hpp"

namespace obsynth {

// Designs auto passes over, with the reason, a clause that follows "<method>: " (a budget
// stopped their verdict or build, or their closed-loop trial failed).
struct ExcludedDesign {
  std::string method, reason;
};

struct SynthesisOptions {
  std::vector<std::string> methods = {"auto"};
  DesignOptions design;
  EmitOptions emit;
  // Designs whose build an earlier attempt's time or memory budget stopped (the worker was
  // killed): auto goes on with the next design that applies.
  std::vector<ExcludedDesign> auto_excluded;
};

struct Synthesis {
  std::vector<OutputFile> files;
  std::vector<std::string> chosen;  // methods emitted
  std::string explanation;          // why auto chose what it chose
  // One per emitted observer whose own certificate proves nothing here (printed by the main
  // job as warnings, at the top of the report).
  std::vector<std::string> warnings;
};

// The methods to build: `auto` resolved through the registry (of the designs that apply, the one
// with the strongest guarantee, then the cheapest: registry order; passing over `excluded`), names
// checked. `explanation` says why auto chose what it chose; `auto_choice`, when given, receives
// that choice.
std::vector<std::string> resolve_methods(PlanSet& plans, const std::vector<std::string>& asked,
                                         std::string& explanation,
                                         const std::vector<ExcludedDesign>& excluded = {},
                                         std::string* auto_choice = nullptr,
                                         Guarantee* auto_guarantee = nullptr);
// The same with a plan set of its own (the model's option lines as the options).
std::vector<std::string> resolve_methods(const Analysis& a, const std::vector<std::string>& asked,
                                         std::string& explanation,
                                         const std::vector<ExcludedDesign>& excluded = {},
                                         std::string* auto_choice = nullptr,
                                         Guarantee* auto_guarantee = nullptr);

// The design options with the model file's `option` lines added; a value given on the command
// line wins. An option no registered design declares is a UserError at its line.
DesignOptions with_model_options(const Model& m, const DesignOptions& given);

// Builds the spec of one registered method (the model's `option` lines merged in) (UserError when
// it does not apply).
ObserverSpec build_design(PlanSet& plans, const std::string& method);
// The same with a plan set of its own.
ObserverSpec build_design(const Analysis& a, const std::string& method, const DesignOptions& o);

// One method (a name, or auto) chosen and built as the main job would: auto passes over a
// design whose build stops or whose closed-loop trial fails (app/trial.hpp).
struct BuiltDesign {
  std::string method;
  ObserverSpec spec;
};
BuiltDesign choose_and_build(const Analysis& a, const std::string& method,
                             const DesignOptions& design, std::string& explanation);

Synthesis synthesize(const Analysis& a, const SynthesisOptions& opt);

}  // namespace obsynth
