// The design registry: one entry per observer design (design.md §3). The method list, the
// command line's flags and help, --list-methods, `--method auto`, the CMake function and the
// tests all read it. Adding a design: one file pair in synth/designs/ plus one line in
// registry.cpp.
#pragma once

#include <string>
#include <vector>

#include "analysis/analysis.hpp"
#include "designs/spec.hpp"

namespace obsynth {

// How strongly a design's own certificate guarantees convergence on this model. `--method auto`
// ranks the designs that apply by it first, then by cost (registry order).
enum class Guarantee {
  none,      // the design applies, but its certificate proves nothing here (or has none)
  partial,   // proved on a sub-box only, or a bound from samples (labelled "sampled")
  rigorous,  // a proven enclosure over the whole domain box
};
const char* guarantee_name(Guarantee g);

// Whether a design's theorem applies to an analysed model, and why (or why not).
struct Verdict {
  bool applies = false;
  std::vector<std::string> reasons;
  Guarantee guarantee = Guarantee::none;
  std::string guarantee_text;  // one line: what is proved, where, and how (rigorous / sampled)
  std::string text() const;    // reasons joined with "; "
};

struct Design {
  std::string name;     // method name, e.g. "canonical"
  std::string summary;  // one line for --list-methods and reports
  std::vector<DesignOptionInfo> options;
  // Whether applies()/build() read the canonical-form analysis (r, frame, brackets, T, l).
  // When every method asked for says false, the command line skips those stages.
  bool needs_canonical_form = true;
  Verdict (*applies)(const Analysis&) = nullptr;
  // Optional: the certificate behind the verdict (seconds on large models): fills the
  // guarantee, and may withdraw `applies` when the certificate shows the design useless here.
  // The main job always runs it; `check` only with --certify.
  void (*assess)(const Analysis&, Verdict&) = nullptr;
  // Throws UserError (why it does not apply, or a bad option) on failure.
  ObserverSpec (*build)(const Analysis&, const DesignOptions&) = nullptr;
  // Whether `--method all` and `--method auto` consider it (false for designs that build large
  // numeric tables: chosen by name only).
  bool in_all = true;
  // Direct feedthrough. A separable y = h0(x) + k(u) is analysed as h0 with y - k(u) observed
  // (Model::output_offset): a design whose generated functions read y (with u among their
  // arguments) takes it by substitution; one that feeds y to filters or differentiators itself
  // does not. A feedthrough that does not split needs a design built on h(x, u) itself.
  bool observes_output_offset = true;
  bool accepts_feedthrough = false;
  // Whether applies() runs a certificate search (seconds, not milliseconds): `check` runs it
  // only with --certify; the main job always does for the methods it considers.
  bool verdict_searches = false;
};

// The design's verdict, after the registry's own checks (feedthrough traits above).
// assess: also run the design's certificate (Design::assess).
Verdict design_verdict(const Design& d, const Analysis& a, bool assess = true);

// Implemented designs, in the order of their cost (`--method auto` breaks ties by it).
const std::vector<Design>& design_registry();
// Method names of design.md §3 that no registered design implements yet.
const std::vector<std::string>& planned_methods();
// nullptr when the name is not registered.
const Design* find_design(const std::string& name);
// Every option name any design declares, once, in registry order.
std::vector<DesignOptionInfo> all_design_options();

}  // namespace obsynth
