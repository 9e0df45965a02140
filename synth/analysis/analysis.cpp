#include "analysis/analysis.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>

#include "analysis/output_transformation.hpp"
#include "symbolic/expr_print.hpp"

namespace obsynth {

const char* stage_status_name(StageStatus s) {
  switch (s) {
    case StageStatus::completed:
      return "completed";
    case StageStatus::stopped:
      return "stopped";
    case StageStatus::not_run:
      return "not run";
    case StageStatus::not_needed:
      return "not needed";
  }
  return "";
}

const std::vector<std::string>& pipeline_stages() {
  static const std::vector<std::string> stages = {"lie", "observability", "frame", "conditions",
                                                  "diffeomorphism"};
  return stages;
}

bool Analysis::complete() const {
  return stopped_stage() == nullptr;
}

const StageOutcome* Analysis::stopped_stage() const {
  for (const auto& s : stages)
    if (s.status == StageStatus::stopped) return &s;
  return nullptr;
}

bool Analysis::completed(const std::string& stage) const {
  for (const auto& s : stages)
    if (s.name == stage) return s.status == StageStatus::completed;
  return true;
}

bool Analysis::lost(const std::string& stage) const {
  for (const auto& s : stages)
    if (s.name == stage)
      return s.status == StageStatus::stopped || s.status == StageStatus::not_run;
  return false;
}

namespace {

// Follows the stages as they begin. Keeps the results as they stood when the running stage
// began (what a stop in it leaves: a stage's results are all or nothing), offers them to the
// checkpoint, and finally says which stage completed, stopped, did not run or was not needed.
class StageLog {
 public:
  StageLog(Analysis& a, const AnalysisOptions& opt) : a_(a), opt_(opt) {}

  void attach(const Budget& budget) { budget_ = &budget; }
  const std::string& current() const { return current_; }

  void began(const std::string& stage) {
    current_ = stage;
    if (std::find(begun_.begin(), begun_.end(), stage) == begun_.end()) begun_.push_back(stage);
    // analyse_observability and analyse_canonical set fields up before their first stage
    // begins: a stop in that stage loses their whole result.
    before_.observability = stage == "lie" ? Observability{} : a_.observability;
    before_.canonical = stage == "frame" ? CanonicalForm{} : a_.canonical;
    checkpoint();
    // Told after the checkpoint, so that a watchdog killing the process in between names the
    // stage the last checkpoint says was stopped.
    if (opt_.on_stage) opt_.on_stage(stage);
  }

  // The running stage was stopped: back to the results from before it.
  void restore() {
    a_.observability = std::move(before_.observability);
    a_.canonical = std::move(before_.canonical);
  }

  // The results before the running stage, offered as what to report should it never end.
  void checkpoint() const {
    if (!opt_.on_checkpoint) return;
    Analysis partial = a_;
    partial.observability = before_.observability;
    partial.canonical = before_.canonical;
    if (budget_) partial.timings_ms = budget_->timings_ms();
    partial.stages = outcomes(opt_.checkpoint_reason);
    opt_.on_checkpoint(partial);
  }

  // Every stage's outcome; stop_reason non-empty: the running stage was stopped.
  std::vector<StageOutcome> outcomes(const std::string& stop_reason) const {
    std::vector<StageOutcome> out;
    bool after_stop = false;
    for (const auto& name : order()) {
      StageOutcome o{name, StageStatus::completed, {}};
      const bool begun = std::find(begun_.begin(), begun_.end(), name) != begun_.end();
      if (after_stop) {
        o.status = StageStatus::not_run;
        o.reason = "an earlier stage was stopped";
      } else if (!stop_reason.empty() && name == current_) {
        o.status = StageStatus::stopped;
        o.reason = stop_reason;
        after_stop = true;
      } else if (!begun) {
        o.status = StageStatus::not_needed;
        o.reason = not_needed_reason();
      }
      out.push_back(std::move(o));
    }
    return out;
  }

 private:
  // The pipeline's stages, with any other stage that began inserted after the one before it.
  std::vector<std::string> order() const {
    std::vector<std::string> order = pipeline_stages();
    std::size_t at = 0;
    for (const auto& s : begun_) {
      auto it = std::find(order.begin(), order.end(), s);
      if (it == order.end()) it = order.insert(order.begin() + static_cast<long>(at), s);
      at = static_cast<std::size_t>(it - order.begin()) + 1;
    }
    return order;
  }

  std::string not_needed_reason() const {
    const CanonicalForm& cf = a_.canonical;
    if (!cf.applicable && !cf.not_applicable.empty()) return cf.not_applicable;
    if (cf.applicable && !cf.linearizable) return "the bracket conditions fail";
    return "the analysis ended before it";
  }

  Analysis& a_;
  const AnalysisOptions& opt_;
  const Budget* budget_ = nullptr;
  std::string current_;
  std::vector<std::string> begun_;
  struct {
    Observability observability;
    CanonicalForm canonical;
  } before_;
};

// The bracket conditions failed: look for psi(y) that makes them hold, and verify it by
// analysing the model observed through psi from scratch (rank, frame, conditions, T). A budget
// stop ends the search only (the original form stays).
void try_output_transformation(const Model& m, Budget& budget, const AnalysisOptions& opt,
                               Analysis& a) {
  const CanonicalForm& cf = a.canonical;
  if (!opt.canonical.output_transformation || !cf.applicable || cf.linearizable ||
      cf.y.size() != m.p())
    return;
  const OutputTransformationCandidate cand = output_transformation_candidate(m, cf);
  if (!cand.psi) {
    a.output_transformation_note = "no output transformation y -> psi(y): " + cand.how;
    return;
  }
  const std::string psi_text = fmt::format("[{}]", fmt::join(to_strings(*cand.psi), ", "));
  Model observed = transformed_output(m, *cand.psi, cf.y);
  if (const auto errors = certify::check_definedness(observed).errors(); !errors.empty()) {
    a.output_transformation_note =
        fmt::format("psi(y) = {} ({}) is not defined on the output's range: {}", psi_text, cand.how,
                    errors.front().message);
    return;
  }
  try {
    Observability ob;
    analyse_observability(observed, budget, opt.observability, &ob);
    CanonicalForm t;
    analyse_canonical(observed, ob, budget, opt.canonical, &t);
    if (!t.linearizable) {
      a.output_transformation_note = fmt::format(
          "the candidate psi(y) = {} ({}) does not satisfy every condition", psi_text, cand.how);
      return;
    }
    std::vector<std::pair<std::string, BracketCheck>> checks;
    for (const auto& b : cf.drift)
      if (!b.holds())
        checks.emplace_back(fmt::format("[{}, {}]", cf.tau_name(b.i - 1), cf.tau_name(b.j - 1)), b);
    for (const auto& b : cf.input)
      if (!b.holds()) checks.emplace_back(fmt::format("[g, {}]", cf.tau_name(b.j - 1)), b);
    for (const auto& b : cf.output)
      if (!b.holds()) checks.emplace_back(fmt::format("<dh_{}, {}>", b.i, cf.tau_name(b.j - 1)), b);
    std::vector<std::string> failing;
    for (const auto& c : checks) failing.push_back(c.first);
    // The form's own measurement symbols (measurement_symbols makes fresh ones per analysis).
    GiNaC::exmap rename;
    for (std::size_t i = 0; i < cf.y.size(); ++i) rename[cf.y[i]] = t.y.at(i);
    ExVec psi;
    for (const auto& e : *cand.psi) psi.push_back(e.subs(rename));
    a.output_transformation = Analysis::OutputTransformation{
        std::move(psi),
        t.y,
        std::move(observed),
        fmt::format("{}; the conditions hold for psi(h) (analysed from scratch)", cand.how),
        fmt::format("{}", fmt::join(failing, ", ")),
        std::move(checks)};
    a.canonical = std::move(t);
  } catch (const BudgetExceeded& e) {
    a.output_transformation_note =
        fmt::format("the candidate psi(y) = {} was not verified: {}", psi_text, e.what());
  }
}

void run_stages(const Model& m, const AnalysisOptions& opt, Budget& budget, Analysis& a) {
  // With direct feedthrough the drift analysis reads y = h(x, u0) at the nominal input; the
  // canonical form (y = h(x)) does not apply.
  Model drift_model;
  const bool feedthrough = m.feedthrough();
  if (feedthrough) {
    drift_model = m;
    const GiNaC::exmap u0 = m.nominal_inputs();
    for (auto& e : drift_model.h) e = e.subs(u0);
  }
  const Model& dm = feedthrough ? drift_model : m;
  analyse_observability(dm, budget, opt.observability, &a.observability);
  a.under_inputs =
      analyse_observability_under_inputs(m, a.observability, opt.observability, opt.budget);
  if (!opt.canonical_form)
    a.canonical.not_applicable = "not analysed: " + opt.canonical_skipped;
  else if (feedthrough)
    a.canonical.not_applicable =
        "does not apply: the output depends on the input (direct feedthrough y = h(x,u)); the "
        "observer canonical form needs y = h(x)";
  else if (a.observability.jets)  // no symbolic Lie derivatives: nothing for r, the frame, T
    a.canonical.not_applicable = "skipped: " + a.observability.symbolic_skipped +
                                 "; r, the frame, the brackets, T and l need them";
  else {
    analyse_canonical(m, a.observability, budget, opt.canonical, &a.canonical);
    try_output_transformation(m, budget, opt, a);
  }
}

// y = h(x, u) with h(x, u) - h(x, u0) free of x: h0 = h(x, u0), k(u) = h(x, u) - h0 (a battery's
// terminal voltage OCV(soc) - v1 - R0 i). Every design then observes y - k(u) = h0(x).
Model split_output_offset(const Model& m) {
  if (!m.feedthrough() || !m.output_offset.empty()) return m;
  const GiNaC::exmap u0 = m.nominal_inputs();
  ExVec h0, k;
  for (const auto& e : m.h) {
    const GiNaC::ex base = e.subs(u0);
    const GiNaC::ex rest = (e - base).expand();
    for (const auto& x : m.states)
      if (!rest.diff(x).normal().is_zero()) return m;  // not separable: h(x, u) stays
    h0.push_back(base);
    k.push_back(rest);
  }
  Model out = m;
  out.h = h0;
  out.output_offset = k;
  return out;
}

}  // namespace

Analysis analyse(const Model& given, const AnalysisOptions& opt) {
  const Model m = split_output_offset(given);
  Analysis a;
  a.model = m;
  a.definedness = certify::check_definedness(m);
  if (auto errors = a.definedness.errors(); !errors.empty()) throw UserError(std::move(errors));
  StageLog log(a, opt);
  Budget budget(opt.budget, [&](const std::string& stage) { log.began(stage); });
  log.attach(budget);
  std::string stop_reason;  // non-empty: a budget stopped the running stage
  try {
    run_stages(m, opt, budget, a);
  } catch (const BudgetExceeded& e) {
    if (log.current().empty()) throw;
    stop_reason = e.reason();
  } catch (const std::exception& e) {
    if (!is_out_of_memory(e) || log.current().empty()) throw;
    stop_reason = memory_budget_reason(opt.budget.max_memory_bytes);
  }
  budget.end();
  a.timings_ms = budget.timings_ms();
  if (!stop_reason.empty()) {
    log.restore();
    if (!opt.keep_partial) throw BudgetExceeded(log.current(), stop_reason);
  }
  a.stages = log.outcomes(stop_reason);
  return a;
}

}  // namespace obsynth
