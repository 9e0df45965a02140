// The main job as a pure function: analysis -> chosen designs (registry) -> ObserverSpecs ->
// header texts and reports.
#pragma once

#include <string>
#include <vector>

#include "analysis/analysis.hpp"
#include "app/output_dir.hpp"
#include "designs/spec.hpp"
#include "emit/emit_cxx.hpp"

namespace obsynth {

struct SynthesisOptions {
  std::vector<std::string> methods = {"auto"};
  DesignOptions design;
  EmitOptions emit;
};

struct Synthesis {
  std::vector<OutputFile> files;
  std::vector<std::string> chosen;  // methods emitted
  std::string explanation;          // why auto chose what it chose
};

// The methods to build: `auto` resolved through the registry (first design that applies, in
// registry order), names checked. `explanation` says why auto chose what it chose.
std::vector<std::string> resolve_methods(const Analysis& a, const std::vector<std::string>& asked,
                                         std::string& explanation);

// The design options with the model file's `option` lines added; a value given on the command
// line wins. An option no registered design declares is a UserError at its line.
DesignOptions with_model_options(const Model& m, const DesignOptions& given);

// Builds the spec of one registered method (the model's `option` lines merged in) (UserError when
// it does not apply).
ObserverSpec build_design(const Analysis& a, const std::string& method, const DesignOptions& o);

Synthesis synthesize(const Analysis& a, const SynthesisOptions& opt);

}  // namespace obsynth
