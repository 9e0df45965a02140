// The observer description (IR) every design builds and every consumer reads: the generic
// C++ and C emitters, the simulator, the report renderers, the CMake manifest and the tests.
// A design fills an ObserverSpec once; no consumer re-derives gains, offsets or jet orders.
//
// An observer is a class with an internal state w (size `state_size`), started from an
// estimate xh0 (`init`), advanced by step(dt, u, y) (`update`), and read through the
// estimate map (`estimate`). Its maths lives in `functions`: symbolic vectors over named
// arguments, emitted as straight-line code and evaluated by the simulator through the same
// expression DAG.
#pragma once

#include <ginac/ginac.h>

#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "foundation/report_row.hpp"
#include "front/model.hpp"

namespace obsynth {

// A vector argument of a generated function: element i is the symbol `symbols[i]`, read as
// `name(i)` in the generated code. Runtime parameters are not listed: every function that
// uses one receives the parameter struct (see ObserverSpec::params).
struct FunctionArg {
  enum class Kind {
    state,           // an n-vector in the model's state coordinates ("x")
    input,           // the m inputs ("u")
    output,          // the p outputs ("y")
    observer_state,  // the observer's own state w ("z", size state_size)
    vector,          // another vector of the given size (e.g. "c", jets)
    matrix,          // rows x cols, column-major symbols, read as name(r, c)
  };
  Kind kind = Kind::vector;
  std::string name;  // C++ parameter name
  std::vector<GiNaC::symbol> symbols;
  std::size_t rows = 0, cols = 1;
  std::string type;  // C++ type name inside the class (State, Input, Output, YJet, ...)
};

// One intermediate definition: `symbol = value`, evaluated in order before the outputs (an
// elimination sequence such as T^-1 stays a sequence, never composed and expanded).
struct LetStep {
  GiNaC::symbol symbol;
  GiNaC::ex value;
};

struct GeneratedFunction {
  std::string name;  // e.g. "z_rhs"
  std::string doc;   // one line
  std::vector<FunctionArg> args;
  std::vector<LetStep> lets;
  ExVec outputs;  // column-major when out_cols > 1
  std::size_t out_rows = 0, out_cols = 1;
  std::string out_type;  // C++ type of the result (State, Frame, ...)
};

// How step(dt, u, y) advances the observer state.
enum class UpdateKind {
  ode,            // w' = rhs(w, u, y): one RK4 step with u, y held ("rhs")
  linear_exact,   // w' = A_cl w + c(u, y): w <- Phi(dt) w + Gamma(dt) c, Phi and Gamma exact,
                  // recomputed only when dt changes ("step_constant"; A_cl in closed_loop)
  jets,           // w = jets of y and u from differentiators; x from "reconstruct"
  sampled_delay,  // discrete time at one fixed sample period (SampledDelay): a filter bank
                  // z <- a.*z + g y, a delay line eta = z - e^{A T} z(t - T) in a ring buffer,
                  // and a table-driven estimate switched by the input level; no derivatives
  program,        // the design's own step: ObserverSpec::program, a sequence of the step
                  // program's ops (step_program.hpp) that no kind above lowers to
};

enum class InitKind {
  identity,  // w = xh0
  function,  // w = init(xh0)  (function "init")
};

enum class EstimateKind {
  identity,  // xh = w
  function,  // xh = estimate(w)  (function "estimate")
  newton,    // xh solves T(xh) = w: Newton seeded by the previous estimate, with the
             // inverse Jacobian given by function "inverse_jacobian" (e.g. the frame [tau])
};

// A free parameter of the model, a run-time field of the generated class.
struct RuntimeParam {
  GiNaC::symbol symbol;
  std::string name;
  GiNaC::numeric default_value;
  std::string default_reason;  // e.g. "centre of the domain box [1/2, 2]"
};

// A named design constant, reported and emitted as a class constant.
struct DesignConstant {
  std::string name;  // e.g. "poles"
  std::vector<GiNaC::numeric> values;
  std::string doc;
};

// Constant data of a design, emitted as const arrays (flash): `values` in row-major order of
// `dims`, printed in the output precision.
struct ConstTable {
  std::string name;  // C identifier, e.g. "observation_map"
  std::vector<std::size_t> dims;
  std::vector<double> values;
  std::string doc;  // one line
  std::size_t size() const;
};

// UpdateKind::sampled_delay (the Kreisselmeier-Engel / Garcia-Hernandez finite-time
// observer, seed 004 eq. 10, 15). With dt the fixed sample period, D = delay_steps, each step
//   1. z <- decay .* z + gain * y            (exact zero-order hold of z' = A z + b y, A diag)
//   2. the ring buffer keeps the last D + 1 values of z (and of u[input_index]); once D steps
//      have passed since reset,
//      level = clamp(floor((v - level_lo) / level_step + (level_nearest ? 1/2 : 0)), 0,
//      levels - 1) with v = u[input_index] of this step, or with level_window_mean the mean
//      of the last D samples of it (this one included; level 0 when levels == 1),
//      eta = z - delay .* z(D steps ago), e = metric * eta (a filters x filters matrix), and
//        xh = sum_i x_i w_i / sum_i w_i,  w_i = (epsilon + |e - q[level][i]|_2)^-weight_power
//      over the regular state grid x_i; before that, xh stays the reset estimate.
//      With level_interpolate (and levels > 1) the table is interpolated linearly in v instead:
//      r = clamp((v - level_lo) / level_step, 0, levels - 1), level = min(floor(r), levels - 2),
//      a = r - level, and q[level][i] above is replaced by
//      q[level][i] + a * (q[level + 1][i] - q[level][i]) (level_nearest is then ignored).
//      With a slope_table (dq [levels][points][filters], only with level_window_mean and
//      level_interpolate), the slope of the same D input samples, fitted by least squares,
//        slope = sum_a (a - abar) (u_a - v) / (-dt sum_a (a - abar)^2)  (a = 0 newest .. D - 1,
//        abar = (D - 1) / 2; du/dt forward in time),
//      adds slope * (dq[level][i] + a * (dq[level + 1][i] - dq[level][i])) to that table entry.
// The grid enumerates states row-major: the last state varies fastest; x_i(s) = grid_lo[s] +
// grid_step[s] * index_s. Table shapes: decay, gain, delay [filters]; map [levels][points]
// [filters], metric [filters][filters] row-major (names in ObserverSpec::tables).
struct SampledDelay {
  double sample_period = 0;  // the only dt step() accepts (relative tolerance 1e-6)
  std::size_t delay_steps = 0;
  std::size_t filters = 0;
  std::string decay_table, gain_table, delay_table, metric_table, map_table;
  std::string slope_table;  // empty: no slope correction
  std::vector<double> grid_lo, grid_step;
  std::vector<std::size_t> grid_count;
  std::size_t input_index = 0;
  // p outputs: filter j is fed y[j % outputs] (the filters are dealt round the outputs).
  std::size_t outputs = 1;
  double level_lo = 0, level_step = 1;
  std::size_t levels = 1;
  bool level_nearest = false, level_window_mean = false, level_interpolate = false;
  double epsilon = 0.05;
  int weight_power = 1;
  std::size_t points() const;
};

// A design option (one command-line flag; later also a model-file entry).
struct DesignOptionInfo {
  std::string name;  // flag without dashes, e.g. "poles"
  std::string help;
  std::string default_text;  // shown in --help; empty: computed by the design
};

// Values of the options given for one run, by option name (strings as given).
struct DesignOptions {
  std::map<std::string, std::string> values;
  const std::string* find(const std::string& name) const {
    auto it = values.find(name);
    return it == values.end() ? nullptr : &it->second;
  }
};

// A symmetric matrix held in the observer state as its packed upper triangle, row by row:
// (0,0), (0,1), ..., (0,d-1), (1,1), ..., (d-1,d-1) at w[offset, offset + d(d+1)/2). Functions
// read it through the w symbols; `packed_index` maps (r, c) to the position in w.
struct SymmetricBlock {
  std::string name;  // e.g. "Q" (Riccati), "S" (Kalman-theta); names an accessor in the class
  std::size_t offset = 0;
  std::size_t dim = 0;
  // After every step the block must have a Cholesky factor (LLT); otherwise the step is
  // rejected (state kept) and Status::singular returned. Never a NaN.
  bool keep_positive_definite = true;
  std::size_t packed_size() const { return dim * (dim + 1) / 2; }
  std::size_t packed_index(std::size_t r, std::size_t c) const;  // offset + position, r,c < dim
};

// An extra right-hand-side term of an ODE update that needs a factorised solve, never an
// explicit inverse: rhs[target_offset + i] += (M^-1 v)_i, i < dim, in every RK4 stage.
// M is either a generated function of (w, u) (matrix_function, e.g. the observability matrix
// O(xh) of the high-gain observer) or a SymmetricBlock of w (matrix_block, e.g. S of the
// Kalman-theta observer). v is a generated function of (w, u, y) (vector_function; fold any
// sign into v). A failed factorisation rejects the step with Status::singular: Cholesky fails
// when M is not positive definite; LU (partial pivoting) fails when its smallest pivot is at most
// sqrt(epsilon) times its largest (epsilon of the scalar type: an ill-conditioned M, see
// lu_conditioning_limit in runtime/obsynth/linear_solve.hpp). Either fails on a non-finite result.
struct SolveCorrection {
  enum class Factor { cholesky, lu };
  Factor factor = Factor::lu;
  std::string matrix_function;  // name in `functions` (args like rhs minus y), or empty
  std::string matrix_block;     // name of a SymmetricBlock, or empty
  std::string vector_function;  // name in `functions` (same args as rhs)
  std::size_t target_offset = 0, dim = 0;
  std::string singular_doc;  // where M is singular, for the class comment and the report
};

struct StepProgram;  // step_program.hpp

struct ObserverSpec {
  std::string method;                    // registry name, e.g. "canonical"
  std::string class_suffix;              // class = PascalCase(model) + suffix
  std::string title;                     // one line, e.g. "Canonical-form Luenberger observer"
  std::vector<std::string> description;  // banner lines, each without the leading "// "
  std::vector<std::string> class_doc;    // lines under the title in the class comment

  std::size_t state_size = 0;
  std::string state_name = "w";  // member name prefix, e.g. "zh" or "xh"
  std::string state_doc;
  InitKind init = InitKind::identity;
  UpdateKind update = UpdateKind::ode;
  EstimateKind estimate = EstimateKind::identity;
  // UpdateKind::program: the step as the design wrote it (its estimate and init included);
  // lower() takes it as it is, so a design with a step scheme of its own needs no other file.
  std::shared_ptr<const StepProgram> program;
  std::vector<GeneratedFunction> functions;
  // Which function plays which part (names in `functions`; empty when not used).
  struct Roles {
    std::string init;                     // InitKind::function: w = init(x)
    std::string rhs;                      // ode: rhs(w, u, y); linear_exact: rhs(w, c)
    std::string step_constant;            // linear_exact: c = step_constant(u, y)
    std::string step_basis;               // linear_exact with input_map: b = step_basis(u, y)
    std::string estimate;                 // EstimateKind::function: x = estimate(w)
    std::string newton_map;               // EstimateKind::newton: T(x) = w
    std::string newton_inverse_jacobian;  // EstimateKind::newton: (dT/dx)^-1 at x
    std::string reconstruct;              // jets: w(jets) (then estimate as above)
  } roles;

  // ode: symmetric blocks of w kept positive definite, and a solve term added to rhs.
  std::vector<SymmetricBlock> symmetric_blocks;
  std::optional<SolveCorrection> correction;
  // ode with symmetric blocks or a correction (a guarded step): when > 0, step(dt) splits dt
  // into ceil(dt / max_substep) equal RK4 sub-steps (at most 4096), u and y held, so that a
  // sample period longer than the design's largest safe RK4 step still integrates the observer
  // inside RK4's stability region. 0: one RK4 step per sample.
  GiNaC::numeric max_substep = 0;

  // linear_exact: the closed-loop matrix of w' = A_cl w + c (rows of exact rationals).
  std::vector<std::vector<GiNaC::numeric>> closed_loop;
  bool rk4_for_linear = false;  // linear_exact realised by RK4 on the same ODE instead
  // linear_exact (optional, exact step only): c = input_map b with b = step_basis(u, y) (k
  // entries) and a constant rational n x k matrix (rows): the exact step applies Gamma(dt)
  // input_map, folded once per dt, to b. Empty: the step applies Gamma to c itself.
  std::vector<std::vector<GiNaC::numeric>> input_map;

  // jets: orders of the differentiators (highest derivative estimated) and of what is used.
  std::size_t y_jet_order = 0, u_jet_order = 0;
  std::size_t y_order_used = 0;
  std::vector<std::size_t> u_orders_used;
  double default_epsilon = 0.01;

  int newton_iterations = 8;

  // The largest step at which the observer's own RK4 update is stable (its fastest error
  // dynamics), for the closed-loop trial and simulate's choice of step; 0: any step (exact
  // discretisation, sub-stepping) or unknown.
  double largest_safe_step = 0;

  // sampled_delay: the filter bank, delay line and inverse tables.
  std::optional<SampledDelay> sampled_delay;
  std::vector<ConstTable> tables;
  const ConstTable* table(const std::string& name) const;

  std::vector<RuntimeParam> params;
  std::vector<DesignConstant> constants;
  std::vector<ReportRow> report;
  std::string summary;  // one paragraph for the report
  // What the design's own numbers say against using it as built (predicted peaking out of the
  // box, a gain capped below what the theorem needs): the main job prints each as a warning
  // and the report opens with them.
  std::vector<std::string> warnings;

  const GeneratedFunction* function(const std::string& name) const;
};

// The model's own maps f, g, h as generated functions (every design emits them).
std::vector<GeneratedFunction> model_functions(const Model& m);

// Runtime parameters for the model's free parameters, default: centre of the domain box.
std::vector<RuntimeParam> runtime_params(const Model& m);

// Standard arguments.
FunctionArg state_arg(const Model& m, const std::string& name = "x");
FunctionArg input_arg(const Model& m);
FunctionArg output_arg(const std::vector<GiNaC::symbol>& y);
FunctionArg vector_arg(const std::string& name, const std::string& type,
                       const std::vector<GiNaC::symbol>& symbols,
                       FunctionArg::Kind kind = FunctionArg::Kind::vector);

std::string pascal_case(const std::string& name);

// Whether a non-finite component of argument number `arg` always makes some output of f
// non-finite: every component reaches an output (through the lets), and only through +, -, *,
// division by terms free of the argument and positive integer powers. In IEEE arithmetic each
// of these gives a non-finite result for a non-finite operand (inf * 0 and inf - inf are NaN),
// so testing f's outputs for finiteness also tests the argument. False for anything else (a
// quotient by the argument, tanh, atan, exp(-w) can map a non-finite value to a finite one).
bool outputs_carry_nonfinite(const GeneratedFunction& f, std::size_t arg);

// outputs_carry_nonfinite for the spec's closed-form estimate x = estimate(w, ...): a step may
// then test x alone (false without such an estimate).
bool estimate_shows_nonfinite_state(const ObserverSpec& s);

// A function's let-steps as (symbol, value) pairs, for Dag::let and NumericFunction.
std::vector<std::pair<GiNaC::symbol, GiNaC::ex>> let_pairs(const GeneratedFunction& f);

}  // namespace obsynth
