#include "designs/step_program.hpp"

#include "foundation/diagnostics.hpp"

namespace obsynth {

namespace {

// A step that can be rejected by a failed gain solve or a lost definiteness (ode only).
bool guarded(const ObserverSpec& s) {
  return s.update == UpdateKind::ode && (s.correction || !s.symmetric_blocks.empty());
}

op::VectorField vector_field(const ObserverSpec& s) {
  op::VectorField f;
  f.rhs = s.roles.rhs;
  if (s.update == UpdateKind::linear_exact) f.held = s.roles.step_constant;
  f.guarded = guarded(s);
  if (f.guarded && s.correction) {
    f.solve = *s.correction;
    if (s.correction->matrix_function.empty()) {
      for (const auto& q : s.symmetric_blocks)
        if (q.name == s.correction->matrix_block) f.solve_block = q;
      OBSYNTH_ASSERT(f.solve_block.has_value(),
                     "solve correction names an unknown symmetric block");
    }
  }
  return f;
}

EstimateOp estimate_op(const ObserverSpec& s) {
  switch (s.estimate) {
    case EstimateKind::identity:
      return est::Identity{};
    case EstimateKind::function:
      return est::Function{s.roles.estimate};
    case EstimateKind::newton:
      return est::Newton{s.roles.newton_map, s.roles.newton_inverse_jacobian, s.newton_iterations};
  }
  return est::Identity{};
}

// ode, and linear_exact realised by RK4: the stages, their guards, then the commit.
void lower_rk4(const ObserverSpec& s, StepProgram& p) {
  const op::VectorField f = vector_field(s);
  if (!f.held.empty()) p.step.push_back(op::HoldInput{f.held, false});
  p.step.push_back(op::Rk4{f, f.guarded ? s.max_substep : GiNaC::numeric(0)});
  if (f.guarded) p.step.push_back(op::StageGuard{});
  p.step.push_back(op::FiniteGuard{true, false});
  if (f.guarded)
    for (const auto& q : s.symmetric_blocks)
      if (q.keep_positive_definite) p.step.push_back(op::DefiniteGuard{q});
  p.step.push_back(op::Commit{false});
  p.step.push_back(op::Finish{true});
}

// linear_exact: the discretisation (once per dt), the held input, the exact increment. With a
// closed-form estimate the estimate of the new state is computed first and tested with it (or
// alone when a non-finite state always shows in it), so a rejected step keeps both.
void lower_exact(const ObserverSpec& s, StepProgram& p) {
  const bool basis = !s.input_map.empty();
  p.step.push_back(op::Discretise{basis ? s.input_map.front().size() : 0});
  p.step.push_back(op::HoldInput{basis ? s.roles.step_basis : s.roles.step_constant, basis});
  p.step.push_back(op::ExactLinearStep{basis});
  if (s.estimate == EstimateKind::function) {
    p.step.push_back(op::EstimateLocal{s.roles.estimate});
    p.step.push_back(op::FiniteGuard{!estimate_shows_nonfinite_state(s), true});
    p.step.push_back(op::Commit{true});
    p.step.push_back(op::Finish{false});
  } else {
    p.step.push_back(op::FiniteGuard{true, false});
    p.step.push_back(op::Commit{false});
    p.step.push_back(op::Finish{true});
  }
}

void lower_sampled_delay(const ObserverSpec& s, StepProgram& p) {
  OBSYNTH_ASSERT(s.sampled_delay.has_value(), "sampled_delay update without its description");
  const SampledDelay& d = *s.sampled_delay;
  const bool interpolate = d.level_interpolate && d.levels > 1;
  p.step.push_back(op::SampleGuard{d.sample_period});
  p.step.push_back(op::RingPush{});
  p.step.push_back(op::LevelSelect{d.levels > 1, interpolate,
                                   !d.slope_table.empty() && interpolate && d.level_window_mean});
  p.step.push_back(op::TableLookup{});
  p.step.push_back(op::FiniteGuard{false, true});
  p.step.push_back(op::Commit{true});
  p.step.push_back(op::Finish{false});
}

// The program of a built-in update kind.
StepProgram lower_kind(const ObserverSpec& s) {
  StepProgram p;
  p.estimate = estimate_op(s);
  if (s.init == InitKind::function) p.init = s.roles.init;
  switch (s.update) {
    case UpdateKind::ode:
      lower_rk4(s, p);
      p.derivative = vector_field(s);
      break;
    case UpdateKind::linear_exact:
      if (s.rk4_for_linear)
        lower_rk4(s, p);
      else
        lower_exact(s, p);
      p.derivative = vector_field(s);
      break;
    case UpdateKind::jets:
      OBSYNTH_ASSERT(s.estimate != EstimateKind::function,
                     "the jets update reconstructs the state or its image under T");
      p.step.push_back(op::JetUpdate{s.y_jet_order, s.u_jet_order});
      p.step.push_back(op::Reconstruct{s.roles.reconstruct});
      p.step.push_back(op::Finish{true});
      break;
    case UpdateKind::sampled_delay:
      lower_sampled_delay(s, p);
      break;
    case UpdateKind::program:
      OBSYNTH_ASSERT(false, "UpdateKind::program is not a built-in kind");
  }
  return p;
}

}  // namespace

StepProgram lower(const ObserverSpec& s) {
  OBSYNTH_ASSERT(s.update != UpdateKind::program || s.program != nullptr,
                 "UpdateKind::program without its program");
  // The design's own step is taken as it wrote it.
  StepProgram p = s.update == UpdateKind::program ? *s.program : lower_kind(s);
  p.singular = p.has<op::StageGuard>() || p.has<op::DefiniteGuard>();
  p.not_converged = p.newton();
  return p;
}

std::string rejection_doc(const StepProgram& p) {
  const op::Rk4* r = p.find<op::Rk4>();
  if (!r || !r->field.guarded) return "";
  std::string names, out;
  for (const auto& o : p.step)
    if (const auto* g = std::get_if<op::DefiniteGuard>(&o))
      names += (names.empty() ? "" : ", ") + g->block.name;
  if (r->field.solve) out = "when a gain solve fails in any stage";
  if (!names.empty())
    out += (out.empty() ? "" : ", or ") + ("when " + names + " is no longer positive definite");
  return out;
}

}  // namespace obsynth
