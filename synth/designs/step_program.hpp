// The step program (issue 19): what an observer's step(dt, u, y) does, as a short sequence of
// typed operations, with the estimate it ends in and its continuous-time vector field.
//
// lower(spec) is the one place that reads the spec's update, estimate and init kinds and decides
// the sequence: which guards a step has and in which order (and the status each returns), the
// sub-stepping of RK4, whether the exact step computes the estimate before it commits the state,
// which statuses the observer can return. The C++ and C back ends print the program (each op from
// a small template of its language) and the simulator interprets it; none of them re-decides the
// sequence from UpdateKind or EstimateKind.
//
// Working values of a step: the observer state before the step (`w_old`), the new state being
// computed (`w`, not yet the observer's), the held input vector (`c` or `b`), the jets, and the
// new estimate `x` when it is computed before the commit. A guard that fails returns its status
// at once with the observer's state and estimate unchanged.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "designs/spec.hpp"

namespace obsynth {

namespace op {

// w' = rhs(w, u, y), or w' = rhs(w, c) with c = held(u, y) (linear_exact realised by RK4), plus
// with a solve the term M^-1 v in rows target_offset.. (SolveCorrection). `guarded`: every
// stage reports whether its solve succeeded (the step then has a StageGuard).
struct VectorField {
  std::string rhs;
  std::string held;  // step_constant when rhs reads c; empty: rhs reads (u, y)
  std::optional<SolveCorrection> solve;
  std::optional<SymmetricBlock> solve_block;  // the block M is read from (matrix_block)
  bool guarded = false;
};

// Recomputes the exact discretisation when dt differs from the last one: E = e^{A_cl dt} - I and
// Gamma (Gamma B with an input map of `basis` columns). Failure: Status::non_finite.
struct Discretise {
  std::size_t basis = 0;  // columns of B; 0: no input map
};

// c = function(u, y) (or b = function(u, y) with an input map), constant over the step.
struct HoldInput {
  std::string function;
  bool basis = false;
};

// w = w_old + (E w_old + Gamma c), the increment added once (Gamma B b with an input map).
struct ExactLinearStep {
  bool basis = false;
};

// One RK4 step of the field from w_old into w, u and y held; with max_substep > 0 in
// ceil(dt / max_substep) equal sub-steps (at most 4096).
struct Rk4 {
  VectorField field;
  GiNaC::numeric max_substep = 0;
};

// A stage's solve failed (field.guarded): Status::singular.
struct StageGuard {};

// A non-finite value in w (state) and/or x (estimate): Status::non_finite.
struct FiniteGuard {
  bool state = true;
  bool estimate = false;
};

// The symmetric block of w has no Cholesky factor: Status::singular.
struct DefiniteGuard {
  SymmetricBlock block;
};

// x = function(w), the estimate of the new state, before the commit.
struct EstimateLocal {
  std::string function;
};

// The observer's state becomes w (and its estimate x).
struct Commit {
  bool estimate = false;
};

// The step's status: the estimate program's on the committed state, or ok.
struct Finish {
  bool update_estimate = true;
};

// The output and input differentiators take the samples y, u (JetDifferentiator, C kernel
// obsynth_jet_update); failure: Status::non_finite.
struct JetUpdate {
  std::size_t y_order = 0, u_order = 0;
};

// The observer state from the jets: w = function(yj, uj).
struct Reconstruct {
  std::string function;
};

// SampledDelay: dt must be the sample period (relative 1e-6), u and y finite; else
// Status::non_finite.
struct SampleGuard {
  double period = 0;
};

// SampledDelay: z <- decay .* z + gain y into the next ring slot (and the input selecting the
// level); until delay_steps samples have passed: Status::ok, estimate kept.
struct RingPush {};

// SampledDelay: the input level (and its interpolation weight and slope) of this step.
struct LevelSelect {
  bool by_input = true;      // false: one table (level 0), the input unused
  bool interpolate = false;  // linear in the input between two tables
  bool slope = false;        // with the slope tables (least-squares slope over the window)
};

// SampledDelay: eta = M (z - delay .* z(D ago)), x = the kernel-weighted mean over the grid of
// the level's table (interpolated, slope-corrected as LevelSelect says).
struct TableLookup {};

}  // namespace op

using StepOp = std::variant<op::Discretise, op::HoldInput, op::ExactLinearStep, op::Rk4,
                            op::StageGuard, op::FiniteGuard, op::DefiniteGuard, op::EstimateLocal,
                            op::Commit, op::Finish, op::JetUpdate, op::Reconstruct, op::SampleGuard,
                            op::RingPush, op::LevelSelect, op::TableLookup>;

namespace est {
// xh = w; Status::non_finite when not finite.
struct Identity {};
// xh = function(w); a non-finite x keeps the estimate: Status::non_finite.
struct Function {
  std::string function;
};
// xh solves map(xh) = w: Newton seeded by the previous estimate with inverse_jacobian (column-
// major); Status::not_converged after `iterations`, non_finite on a non-finite residual.
struct Newton {
  std::string map, inverse_jacobian;
  int iterations = 8;
};
}  // namespace est

using EstimateOp = std::variant<est::Identity, est::Function, est::Newton>;

struct StepProgram {
  std::vector<StepOp> step;
  EstimateOp estimate;
  // The observer as a continuous-time system (ode and linear_exact): d/dt w = field(w, u, y).
  std::optional<op::VectorField> derivative;
  std::string init;  // w = init(xh0); empty: w = xh0
  // Statuses beyond ok and non_finite that step() can return.
  bool singular = false;       // a StageGuard or a DefiniteGuard
  bool not_converged = false;  // a Newton estimate

  template <class T>
  const T* find() const {
    for (const auto& o : step)
      if (const T* t = std::get_if<T>(&o)) return t;
    return nullptr;
  }
  template <class T>
  bool has() const {
    return find<T>() != nullptr;
  }
  bool newton() const { return std::holds_alternative<est::Newton>(estimate); }
};

StepProgram lower(const ObserverSpec& s);

// When a guarded RK4 step is rejected, for its comment: "when a gain solve fails in any stage,
// or when Q is no longer positive definite" (empty without a guarded RK4 step).
std::string rejection_doc(const StepProgram& p);

// For std::visit over the ops: overloaded{[](const op::Rk4&) {...}, ...}.
template <class... F>
struct overloaded : F... {
  using F::operator()...;
};
template <class... F>
overloaded(F...) -> overloaded<F...>;

}  // namespace obsynth
