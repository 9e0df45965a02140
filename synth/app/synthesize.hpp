// The main job as a pure function: analysis -> chosen designs -> header texts and reports.
#pragma once

#include <string>
#include <vector>

#include "analysis/analysis.hpp"
#include "app/output_dir.hpp"
#include "designs/observers.hpp"
#include "emit/emit_header.hpp"

namespace obsynth {

struct SynthesisOptions {
  std::vector<std::string> methods = {"auto"};
  CanonicalDesignOptions canonical;
  EmitOptions emit;
};

struct Synthesis {
  std::vector<OutputFile> files;
  std::vector<std::string> chosen;  // methods emitted
  std::string explanation;          // why auto chose what it chose
};

// Every method name of design.md §3, and whether this version implements it.
const std::vector<std::string>& all_methods();
bool is_implemented(const std::string& method);

Synthesis synthesize(const Analysis& a, const SynthesisOptions& opt);

}  // namespace obsynth
