// The design registry: one entry per observer design (design.md §3). The method list, the
// command line's flags and help, --list-methods, `--method auto`, the CMake function and the
// tests all read it. Adding a design: one file pair in synth/designs/ plus one line in
// registry.cpp.
#pragma once

#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>
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

// One design on one analysed model with one set of options. Its verdict, its certificate and
// its build share their work (a certificate search runs once per plan, not once per call), and
// whoever holds the plan decides how long that work is kept: nothing is cached behind the
// caller's back. The analysis must outlive the plan.
class Plan {
 public:
  virtual ~Plan() = default;
  // Whether the design's theorem applies, and why (or why not).
  virtual Verdict verdict() = 0;
  // The certificate behind the verdict (seconds on large models): fills the guarantee, and may
  // withdraw `applies` when the certificate shows the design useless here. The main job always
  // runs it; `check` only with --certify.
  virtual void assess(Verdict&) {}
  // The observer description. Throws UserError (why it does not apply, or a bad option).
  virtual ObserverSpec build() = 0;
};
using PlanFactory = std::unique_ptr<Plan> (*)(const Analysis&, const DesignOptions&);

// A plan for a design whose verdict, certificate and build share nothing worth keeping: each
// calls its function (Assess may be nullptr).
template <Verdict (*Applies)(const Analysis&),
          ObserverSpec (*Build)(const Analysis&, const DesignOptions&),
          void (*Assess)(const Analysis&, Verdict&) = nullptr>
std::unique_ptr<Plan> stateless_plan(const Analysis& a, const DesignOptions& o) {
  class Stateless final : public Plan {
   public:
    Stateless(const Analysis& a, const DesignOptions& o) : a_(a), o_(o) {}
    Verdict verdict() override { return Applies(a_); }
    void assess(Verdict& v) override {
      if constexpr (Assess != nullptr) Assess(a_, v);
    }
    ObserverSpec build() override { return Build(a_, o_); }

   private:
    const Analysis& a_;
    DesignOptions o_;
  };
  return std::make_unique<Stateless>(a, o);
}

// Work a plan computes on first use and keeps (a design's search, its tuning, its tables).
template <class Work>
class Lazy {
 public:
  explicit Lazy(std::function<Work()> compute) : compute_(std::move(compute)) {}
  const Work& get() const {
    if (!work_) work_.emplace(compute_());
    return *work_;
  }

 private:
  std::function<Work()> compute_;
  mutable std::optional<Work> work_;
};

// The plan of a design with costly work shared by its verdict and its build: Compute runs on
// the model and the options at most once per plan, when VerdictOf or BuildFrom first reads it
// (a verdict that fails on a cheaper ground never starts the search).
template <class Work, Work (*Compute)(const Model&, const DesignOptions&),
          Verdict (*VerdictOf)(const Analysis&, const Lazy<Work>&),
          ObserverSpec (*BuildFrom)(const Analysis&, const Work&)>
std::unique_ptr<Plan> work_plan(const Analysis& a, const DesignOptions& o) {
  class Shared final : public Plan {
   public:
    Shared(const Analysis& a, const DesignOptions& o) : a_(a), o_(o) {}
    Verdict verdict() override { return VerdictOf(a_, work_); }
    ObserverSpec build() override { return BuildFrom(a_, work_.get()); }

   private:
    const Analysis& a_;
    DesignOptions o_;
    Lazy<Work> work_{[this] { return Compute(a_.model, o_); }};
  };
  return std::make_unique<Shared>(a, o);
}

struct Design {
  std::string name;     // method name, e.g. "canonical"
  std::string summary;  // one line for --list-methods and reports
  std::vector<DesignOptionInfo> options;
  // Whether the plan reads the canonical-form analysis (r, frame, brackets, T, l). When every
  // method asked for says false, the command line skips those stages.
  bool needs_canonical_form = true;
  // Makes the design's plan for an analysed model and the options given.
  PlanFactory plan = nullptr;
  // Whether `--method all` and `--method auto` consider it (false for designs that build large
  // numeric tables: chosen by name only).
  bool in_all = true;
  // Direct feedthrough. A separable y = h0(x) + k(u) is analysed as h0 with y - k(u) observed
  // (Model::output_offset): a design whose generated functions read y (with u among their
  // arguments) takes it by substitution; one that feeds y to filters or differentiators itself
  // does not. A feedthrough that does not split needs a design built on h(x, u) itself.
  bool observes_output_offset = true;
  bool accepts_feedthrough = false;
  // Whether the verdict runs a certificate search (seconds, not milliseconds): `check` runs it
  // only with --certify; the main job always does for the methods it considers.
  bool verdict_searches = false;
  // Whether its plan's assess() runs a certificate of its own (the report says when it did not).
  bool has_assessment = false;
  // How many outputs it handles (0: any number); the registry refuses more with that reason.
  std::size_t max_outputs = 0;
  std::string outputs_note;  // why no more outputs (appended to the refusal)
  // Whether it can observe a state that the drift alone does not, along persistent inputs
  // (persistent_input_designs names it, with this note); and whether it needs the model
  // uniformly observable for that.
  bool observes_along_inputs = false;
  std::string along_inputs_note;
  bool needs_uniform_observability = false;

  // One-shot conveniences with a fresh plan (tests and tools; the commands hold a PlanSet).
  Verdict applies(const Analysis& a, const DesignOptions& o = {}) const {
    return plan(a, o)->verdict();
  }
  ObserverSpec build(const Analysis& a, const DesignOptions& o) const {
    return plan(a, o)->build();
  }
};

// The design's verdict on its plan, after the registry's own checks (feedthrough traits,
// definedness). assess: also run the design's certificate (Plan::assess).
Verdict design_verdict(const Design& d, Plan& plan, const Analysis& a, bool assess = true);
// The same on a fresh plan with default options (tests and tools).
Verdict design_verdict(const Design& d, const Analysis& a, bool assess = true);

// The plans of every design for one analysis and one set of options, made on first use and
// kept for the holder's scope: auto's ranking, the warnings, the report and the build share
// them, and each design's verdict (with or without its certificate) is computed once.
class PlanSet {
 public:
  PlanSet(const Analysis& a, DesignOptions o) : a_(a), options_(std::move(o)) {}
  const Analysis& analysis() const { return a_; }
  const DesignOptions& options() const { return options_; }
  const Verdict& verdict(const Design& d, bool assess = true);
  ObserverSpec build(const Design& d);

 private:
  Plan& plan(const Design& d);
  const Analysis& a_;
  DesignOptions options_;
  std::map<std::string, std::unique_ptr<Plan>> plans_;
  std::map<std::pair<std::string, bool>, Verdict> verdicts_;
};

// Implemented designs, in the order of their cost (`--method auto` breaks ties by it).
const std::vector<Design>& design_registry();
// Method names of design.md §3 that no registered design implements yet.
const std::vector<std::string>& planned_methods();
// nullptr when the name is not registered.
const Design* find_design(const std::string& name);
// The designs that can observe along persistent inputs, for this model's analysis under inputs
// (Design::observes_along_inputs), as one line for reports and diagnostics.
std::string persistent_input_designs(const ObservabilityUnderInputs& u);

// Design options are namespaced by their design automatically: an option `o` that design `d`
// declares is also accepted as `d.o` (`--canonical.poles`, `--high-gain.poles`). A bare `--o`
// reaches every design that declares `o`; `d.o` overrides it for `d` alone.
std::string qualified_option_name(const Design& d, const std::string& option);
// d's own view of the run's options: the options it declares, by their bare names (the qualified
// value when given, else the bare one); nothing else, so that a design never reads another's.
DesignOptions options_for(const Design& d, const DesignOptions& given);

// Every option name any design declares, once, in registry order, then every qualified name.
std::vector<DesignOptionInfo> all_design_options();

}  // namespace obsynth
