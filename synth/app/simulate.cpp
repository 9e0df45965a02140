#include "app/simulate.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>

#include "app/svg_plot.hpp"
#include "app/synthesize.hpp"
#include "certify/sampling.hpp"
#include "designs/registry.hpp"
#include "designs/step_program.hpp"
#include "front/parse.hpp"
#include "obsynth/c_kernels.hpp"
#include "obsynth/differentiator.hpp"
#include "symbolic/dag.hpp"
#include "symbolic/expr_print.hpp"

namespace obsynth {

namespace {

using Vec = std::vector<double>;

std::vector<std::string> names_of(const std::vector<GiNaC::symbol>& s) {
  std::vector<std::string> out;
  for (const auto& x : s) out.push_back(x.get_name());
  return out;
}

std::vector<std::string> concat_names(std::vector<std::string> a,
                                      const std::vector<std::string>& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

Vec concat(const Vec& a, const Vec& b) {
  Vec c(a);
  c.insert(c.end(), b.begin(), b.end());
  return c;
}

// Classical RK4 on a vector field of arbitrary dimension: the stages of the C kernel
// (obsynth_rk4_stage, as the generated steps), the field evaluated at t, t + dt/2, t + dt/2, t +
// dt.
template <class F>
void rk4(F&& rhs, double t, double dt, Vec& x) {
  const int n = static_cast<int>(x.size());
  Vec acc(x.size()), point(x.size());
  const double at[4] = {t, t + dt / 2, t + dt / 2, t + dt};
  Vec k = rhs(at[0], x);
  for (int stage = 0; stage < 3; ++stage) {
    c_double::obsynth_rk4_stage(stage, dt, n, x.data(), k.data(), acc.data(), point.data());
    k = rhs(at[stage + 1], point);
  }
  c_double::obsynth_rk4_stage(3, dt, n, x.data(), k.data(), acc.data(), x.data());
}

// Runtime-sized access to the runtime's fixed-order differentiator.
struct Jet {
  virtual ~Jet() = default;
  virtual void reset(double y0) = 0;
  virtual void update(double dt, double y) = 0;
  virtual Vec jet() const = 0;
};

template <int K>
struct JetK : Jet {
  explicit JetK(double eps) : d(eps) {}
  obsynth::JetDifferentiator<double, K> d;
  void reset(double y0) override { d.reset(y0); }
  void update(double dt, double y) override { d.update(dt, y); }
  Vec jet() const override {
    const auto j = d.jet();
    return Vec(j.data(), j.data() + K + 1);
  }
};

std::unique_ptr<Jet> make_jet(std::size_t k, double eps) {
  switch (k) {
    case 0:
      return std::make_unique<JetK<0>>(eps);
    case 1:
      return std::make_unique<JetK<1>>(eps);
    case 2:
      return std::make_unique<JetK<2>>(eps);
    case 3:
      return std::make_unique<JetK<3>>(eps);
    case 4:
      return std::make_unique<JetK<4>>(eps);
    case 5:
      return std::make_unique<JetK<5>>(eps);
    case 6:
      return std::make_unique<JetK<6>>(eps);
    case 7:
      return std::make_unique<JetK<7>>(eps);
    default:
      throw UserError(SourceLoc{}, "simulate: the perfect observer is limited to n <= 8 states");
  }
}

// Newton on T(x) = z with (dT/dx)^-1 given: the firmware's iteration (the C kernel's
// obsynth_newton_*); the estimate is its last finite iterate.
Vec newton(const NumericFunction& T, const NumericFunction& frame, const Vec& z, Vec x,
           int iterations, double tol) {
  const int n = static_cast<int>(z.size());
  Vec Tx, r(z.size()), dx(z.size()), x_prev = x;
  c_double::obsynth_newton nw;
  c_double::obsynth_newton_begin(&nw, z.data(), x.data(), n, iterations, tol);
  for (;;) {
    Tx = T(x);
    if (!c_double::obsynth_newton_residual(&nw, Tx.data(), z.data(), n, r.data(), x.data(),
                                           x_prev.data()))
      return x;
    c_double::obsynth_newton_step(frame(x).data(), r.data(), n, dx.data());
    c_double::obsynth_newton_apply(&nw, dx.data(), n, x.data(), x_prev.data());
  }
}

std::string csv_header(const std::vector<std::string>& names) {
  std::string h = "t";
  for (const auto& s : names) h += "," + s;
  for (const auto& s : names) h += "," + s + "_hat";
  return h + "\n";
}

}  // namespace

namespace {

bool finite(const Vec& v) {
  for (double d : v)
    if (!std::isfinite(d)) return false;
  return true;
}

// The Halton point i in base b, counted from 1 (0 is the box's corner), in (0, 1).
double halton_point(std::size_t i, unsigned base) {
  return radical_inverse(i + 1, base);
}

// The spec's functions as numeric maps: inputs are the arguments' symbols in order; the
// run-time parameters are fixed at their values.
class SpecFunctions {
 public:
  SpecFunctions(const ObserverSpec& s, const GiNaC::exmap& params) : s_(s), params_(params) {}
  const NumericFunction& operator()(const std::string& name) {
    auto it = cache_.find(name);
    if (it != cache_.end()) return it->second;
    const GeneratedFunction* f = s_.function(name);
    OBSYNTH_ASSERT(f != nullptr, "simulate: the spec has no function " + name);
    ExVec out = f->outputs;
    for (auto& e : out) e = e.subs(params_);
    auto lets = let_pairs(*f);
    for (auto& l : lets) l.second = l.second.subs(params_);
    std::vector<std::string> in;
    for (const auto& arg : f->args)
      for (const auto& sym : arg.symbols) in.push_back(sym.get_name());
    return cache_.emplace(name, NumericFunction(lets, out, in)).first->second;
  }

 private:
  const ObserverSpec& s_;
  GiNaC::exmap params_;
  std::map<std::string, NumericFunction> cache_;
};

// E = e^{A dt} - I and Gamma = int_0^dt e^{A s} ds, row-major, by the runtime's kernel (as the
// generated discretise()); false for a bad dt or a non-finite result.
bool exact_discretisation(const ObserverSpec& s, double dt, Vec& E, Vec& Gamma) {
  const std::size_t n = s.closed_loop.size();
  Vec A(n * n), work(4 * n * n);
  for (std::size_t r = 0; r < n; ++r)
    for (std::size_t c = 0; c < n; ++c) A[r * n + c] = s.closed_loop[r][c].to_double();
  E.assign(n * n, 0.0);
  Gamma.assign(n * n, 0.0);
  return c_double::obsynth_discretise(A.data(), static_cast<int>(n), dt, E.data(), Gamma.data(),
                                      work.data()) != 0;
}

// ceil(dt / max_substep), 1..4096 (1 when max_substep is 0): the generated guarded step's kernel.
std::size_t substeps(double dt, const GiNaC::numeric& max_substep) {
  return static_cast<std::size_t>(c_double::obsynth_substeps(dt, max_substep.to_double()));
}

// One observer run: the step program (step_program.hpp) interpreted in double, op by op in the
// program's order, with the spec's functions evaluated through the expression DAG and the
// runtime's C kernels for discretisation, solves, definiteness and the differentiators. A guard
// that fails sets `rejected` (the run stops there); a finiteness guard lets the value through,
// so that the run reports where the observer left the finite numbers.
class ProgramObserver {
 public:
  ProgramObserver(const ObserverSpec& s, const GiNaC::exmap& params, const SimulationOptions& o,
                  std::size_t inputs, std::size_t outputs)
      : s_(s), p_(lower(s)), fn_(s, params), o_(o) {
    if (const auto* j = p_.find<op::JetUpdate>()) {
      for (std::size_t q = 0; q < outputs; ++q)
        y_.push_back(make_jet(j->y_order, s.default_epsilon));
      for (std::size_t k = 0; k < inputs; ++k)
        u_.push_back(make_jet(j->u_order, s.default_epsilon));
    }
  }
  const StepProgram& program() const { return p_; }
  // The RK4 sub-steps the firmware step takes over dt (1 without an Rk4 op or a limit): the
  // continuous-time run takes as many, so that a --dt past the observer's safe step still
  // integrates it inside RK4's stability region, as the generated step does.
  std::size_t substeps_over(double dt) const {
    const auto* r = p_.find<op::Rk4>();
    return r ? substeps(dt, r->max_substep) : 1;
  }

  // y0: the output at xh0, where the differentiators start (JetUpdate).
  void reset(const Vec& xh0, const Vec& y0 = {}) {
    xh_ = xh0;
    w_ = p_.init.empty() ? xh0 : fn_(p_.init)(xh0);
    for (std::size_t q = 0; q < y_.size(); ++q) y_[q]->reset(y0[q]);
    for (auto& d : u_) d->reset(0);
    if (p_.has<op::RingPush>()) {
      const SampledDelay& d = *s_.sampled_delay;
      ring_.assign((d.delay_steps + 1) * d.filters, 0.0);
      u_ring_.assign(d.delay_steps + 1, 0.0);
      head_ = filled_ = level_ = 0;
      frac_ = slope_ = 0;
    }
  }
  // d/dt w at (w, u, y): the program's vector field (the generated derivative()). A failed gain
  // solve sets `rejected`.
  Vec derivative(const Vec& w, const Vec& u, const Vec& y) {
    bool solved = true;
    Vec dw = field(*p_.derivative, w, u, y, nullptr, solved);
    if (!solved) rejected_ = solve_failure(*p_.derivative);
    return dw;
  }
  // The firmware step with u, y held over dt.
  void step(double dt, const Vec& u, const Vec& y) {
    Step st{dt, u, y, w_, {}, {}, true};
    for (const auto& o : p_.step)
      if (!std::visit([&](const auto& op) { return run(op, st); }, o)) return;
  }
  // Why the last step or derivative was rejected (empty: it was not).
  const std::string& rejected() const { return rejected_; }
  void set_state(const Vec& w) {
    w_ = w;
    for (const auto& o : p_.step)
      if (const auto* g = std::get_if<op::DefiniteGuard>(&o)) definite(*g, w_);
    update_estimate();
  }
  const Vec& state() const { return w_; }
  const Vec& estimate() const { return xh_; }

 private:
  // The working values of one step.
  struct Step {
    double dt;
    const Vec &u, &y;
    Vec w, x, held;
    bool solved;
  };

  bool run(const op::Discretise& d, Step& st) {
    if (st.dt == dt_) return true;
    if (!exact_discretisation(s_, st.dt, E_, Gamma_)) {
      rejected_ = "the exact discretisation failed (a bad dt or a non-finite e^{A dt})";
      return false;
    }
    if (d.basis > 0) {  // Gamma B, folded once per dt as the generated discretise()
      const std::size_t n = s_.closed_loop.size(), k = d.basis;
      Vec gb(n * k, 0.0);
      for (std::size_t i = 0; i < n; ++i)
        for (std::size_t j = 0; j < k; ++j)
          for (std::size_t r = 0; r < n; ++r)
            gb[i * k + j] += Gamma_[i * n + r] * s_.input_map[r][j].to_double();
      Gamma_ = gb;
    }
    dt_ = st.dt;
    return true;
  }
  bool run(const op::HoldInput& h, Step& st) {
    st.held = fn_(h.function)(concat(st.u, st.y));
    return true;
  }
  // w + (E w + Gamma c), the increment added once: the C step's kernel.
  bool run(const op::ExactLinearStep&, Step& st) {
    c_double::obsynth_exact_step(E_.data(), Gamma_.data(), w_.data(), st.held.data(),
                                 static_cast<int>(w_.size()), static_cast<int>(st.held.size()), 1,
                                 st.w.data());
    return true;
  }
  bool run(const op::Rk4& r, Step& st) {
    const std::size_t steps = substeps(st.dt, r.max_substep);
    for (std::size_t k = 0; k < steps; ++k)
      rk4([&](double, const Vec& w) { return field(r.field, w, st.u, st.y, &st.held, st.solved); },
          0, st.dt / static_cast<double>(steps), st.w);
    return true;
  }
  bool run(const op::StageGuard&, Step& st) {
    if (st.solved) return true;
    rejected_ = solve_failure(find_field());
    return false;
  }
  bool run(const op::FiniteGuard&, Step&) { return true; }
  bool run(const op::DefiniteGuard& g, Step& st) { return definite(g, st.w); }
  bool run(const op::EstimateLocal& e, Step& st) {
    st.x = fn_(e.function)(st.w);
    return true;
  }
  bool run(const op::Commit& c, Step& st) {
    w_ = st.w;
    if (c.estimate) xh_ = st.x;
    return true;
  }
  bool run(const op::Finish& f, Step&) {
    if (f.update_estimate) update_estimate();
    return false;
  }
  bool run(const op::JetUpdate&, Step& st) {
    for (std::size_t q = 0; q < y_.size(); ++q) y_[q]->update(st.dt, st.y[q]);
    for (std::size_t j = 0; j < u_.size(); ++j) u_[j]->update(st.dt, st.u[j]);
    return true;
  }
  // Arguments (yj, uj): yj output by output; uj column-major (order k outer, input j inner).
  bool run(const op::Reconstruct& r, Step&) {
    Vec in;
    for (const auto& d : y_) {
      const Vec jet = d->jet();
      in.insert(in.end(), jet.begin(), jet.end());
    }
    const std::size_t orders = p_.find<op::JetUpdate>()->u_order + 1;
    for (std::size_t k = 0; k < orders; ++k)
      for (const auto& d : u_) in.push_back(d->jet()[k]);
    w_ = fn_(r.function)(in);
    return true;
  }
  bool run(const op::SampleGuard& g, Step& st) {
    if (std::fabs(st.dt - g.period) <= 1e-6 * g.period) return true;
    rejected_ = "the sample period";
    return false;
  }
  // The delay line, the level and the table estimate: the C kernels obsynth_delay_* (as the
  // generated C step).
  bool run(const op::RingPush&, Step& st) {
    const SampledDelay& d = *s_.sampled_delay;
    return c_double::obsynth_delay_push(ring_.data(), u_ring_.data(), &head_, &filled_,
                                        delay_steps(), static_cast<int>(d.filters),
                                        table(d.decay_table).data(), table(d.gain_table).data(),
                                        st.y.data(), static_cast<int>(d.outputs),
                                        d.levels > 1 ? st.u[d.input_index] : 0.0) != 0;
  }
  bool run(const op::LevelSelect& ls, Step& st) {
    const SampledDelay& d = *s_.sampled_delay;
    level_ = 0;
    frac_ = slope_ = 0;
    if (!ls.by_input) return true;
    c_double::obsynth_delay_level(
        u_ring_.data(), head_, delay_steps(), st.u[d.input_index], d.level_window_mean,
        ls.slope ? &slope_ : nullptr, st.dt, d.level_lo, d.level_step, static_cast<int>(d.levels),
        d.level_nearest, ls.interpolate, &level_, ls.interpolate ? &frac_ : nullptr);
    return true;
  }
  bool run(const op::TableLookup&, Step& st) {
    const SampledDelay& d = *s_.sampled_delay;
    const int pz = static_cast<int>(d.filters), n = static_cast<int>(d.grid_count.size());
    const std::size_t level_size = d.points() * d.filters;
    const double* q = table(d.map_table).data() + static_cast<std::size_t>(level_) * level_size;
    const double* dq = d.slope_table.empty() ? nullptr
                                             : table(d.slope_table).data() +
                                                   static_cast<std::size_t>(level_) * level_size;
    const bool next_level = d.level_interpolate && d.levels > 1;
    const std::vector<int> count(d.grid_count.begin(), d.grid_count.end());
    const c_double::obsynth_delay_grid grid{n, static_cast<int>(d.points()), d.grid_lo.data(),
                                            d.grid_step.data(), count.data()};
    Vec work(2 * d.filters), sx(d.grid_count.size());
    std::vector<int> idx(d.grid_count.size());
    c_double::obsynth_delay_estimate(&grid, ring_.data(), head_, delay_steps(), pz,
                                     table(d.delay_table).data(), table(d.metric_table).data(), q,
                                     next_level ? q + level_size : nullptr, frac_, dq,
                                     dq && next_level ? dq + level_size : dq, slope_, d.epsilon,
                                     d.weight_power, work.data(), idx.data(), sx.data());
    st.x = sx;
    st.w = sx;  // the sampled delay's state is its estimate
    return true;
  }

  // The field at w: rhs(w, u, y) (rhs(w, c) with c held, or computed when `held` is null), plus
  // the solve term; a failed solve clears `solved`.
  Vec field(const op::VectorField& f, const Vec& w, const Vec& u, const Vec& y, const Vec* held,
            bool& solved) {
    if (!f.held.empty()) return fn_(f.rhs)(concat(w, held ? *held : fn_(f.held)(concat(u, y))));
    Vec dw = fn_(f.rhs)(concat(concat(w, u), y));
    if (f.solve && !add_correction(f, w, u, y, dw)) solved = false;
    return dw;
  }
  const op::VectorField& find_field() const { return p_.find<op::Rk4>()->field; }
  static std::string solve_failure(const op::VectorField& f) {
    return "the gain solve failed (" + f.solve->singular_doc + ")";
  }
  // The symmetric block has a Cholesky factor (the runtime's kernel, as the generated step).
  bool definite(const op::DefiniteGuard& g, const Vec& w) {
    Vec work(g.block.dim * g.block.dim + g.block.dim);
    if (c_double::obsynth_packed_positive_definite(w.data(), static_cast<int>(g.block.offset),
                                                   static_cast<int>(g.block.dim), work.data()))
      return true;
    rejected_ = g.block.name + " is no longer positive definite";
    return false;
  }
  // dw[target..] += M^-1 v by the generated code's factorisation (the runtime's kernels).
  bool add_correction(const op::VectorField& f, const Vec& w, const Vec& u, const Vec& y, Vec& dw) {
    const SolveCorrection& k = *f.solve;
    const std::size_t d = k.dim;
    Vec M(d * d);  // row-major
    if (f.solve_block) {
      c_double::obsynth_unpack_symmetric(w.data(), static_cast<int>(f.solve_block->offset),
                                         static_cast<int>(f.solve_block->dim), M.data());
    } else {
      const Vec mv = fn_(k.matrix_function)(concat(w, u));  // column-major
      for (std::size_t r = 0; r < d; ++r)
        for (std::size_t c = 0; c < d; ++c) M[r * d + c] = mv[c * d + r];
    }
    const Vec v = fn_(k.vector_function)(concat(concat(w, u), y));
    Vec x(d);
    const int dim = static_cast<int>(d);
    const int ok = k.factor == SolveCorrection::Factor::cholesky
                       ? c_double::obsynth_solve_cholesky(M.data(), dim, v.data(), x.data())
                       : c_double::obsynth_solve_lu(M.data(), dim, v.data(), x.data());
    if (!ok) return false;
    for (std::size_t i = 0; i < d; ++i) dw[k.target_offset + i] += x[i];
    return true;
  }
  void update_estimate() {
    std::visit(overloaded{[&](const est::Identity&) { xh_ = w_; },
                          [&](const est::Function& e) { xh_ = fn_(e.function)(w_); },
                          [&](const est::Newton& e) {
                            xh_ = newton(fn_(e.map), fn_(e.inverse_jacobian), w_, xh_, e.iterations,
                                         o_.newton_tolerance);
                          }},
               p_.estimate);
  }
  const Vec& table(const std::string& name) const { return s_.table(name)->values; }
  int delay_steps() const { return static_cast<int>(s_.sampled_delay->delay_steps); }

  const ObserverSpec& s_;
  const StepProgram p_;
  SpecFunctions fn_;
  const SimulationOptions& o_;
  Vec w_, xh_;
  Vec E_, Gamma_;  // row-major, for dt_ (Gamma B with an input map)
  double dt_ = 0;
  std::vector<std::unique_ptr<Jet>> y_, u_;  // the differentiators (JetUpdate)
  Vec ring_, u_ring_;                        // the delay line (RingPush)
  int head_ = 0, filled_ = 0, level_ = 0;
  double frac_ = 0, slope_ = 0;
  std::string rejected_;
};

struct Plant {
  NumericFunction field, output, inputs;  // output reads (x, u): h may depend on u
  Vec f(double t, const Vec& x) const { return field(concat(x, inputs({t}))); }
  Vec y(double t, const Vec& x) const { return output(concat(x, inputs({t}))); }
};

std::size_t step_count(const SimulationOptions& opt, std::size_t n) {
  if (opt.x0.size() != n)
    throw UserError(SourceLoc{}, fmt::format("--x0 needs {} values, got {}", n, opt.x0.size()));
  if (opt.xhat0.size() != n)
    throw UserError(SourceLoc{},
                    fmt::format("--xhat0 needs {} values, got {}", n, opt.xhat0.size()));
  if (!(opt.dt > 0) || !(opt.t_end > 0))
    throw UserError(SourceLoc{}, "--dt and --t-end must be positive");
  const double steps = std::ceil(opt.t_end / opt.dt - 1e-9);
  if (steps > 5e7)
    throw UserError(SourceLoc{}, "simulate: more than 5e7 steps; raise --dt or lower --t-end");
  return static_cast<std::size_t>(steps);
}

Plant make_plant(const Model& m, const std::string& u_text, const GiNaC::exmap& params) {
  GiNaC::symbol tsym("t");
  ExVec u_of_t = parse_expression_list(u_text, "--u", {tsym});
  if (m.m() == 0 && u_text == "0") u_of_t.clear();
  if (u_of_t.size() != m.m())
    throw UserError(SourceLoc{},
                    fmt::format("--u needs {} expression{} in t (one per input), got {}", m.m(),
                                m.m() == 1 ? "" : "s", u_of_t.size()));
  ExVec field = m.field(), h = m.measured_outputs();
  for (auto& e : field) e = e.subs(params);
  for (auto& e : h) e = e.subs(params);
  const auto xn = names_of(m.states);
  return {NumericFunction(field, concat_names(xn, names_of(m.inputs))),
          NumericFunction(h, concat_names(xn, names_of(m.inputs))), NumericFunction(u_of_t, {"t"})};
}

// One --plant-param assignment, checked against the model as read: only a free parameter (no
// value in the model file) can differ between plant and observer.
std::pair<const Param*, GiNaC::numeric> plant_assignment(const Model& source,
                                                         const std::string& text) {
  const auto eq = text.find('=');
  if (eq == std::string::npos || eq == 0)
    throw UserError(SourceLoc{}, fmt::format("--plant-param '{}': expected name=value", text));
  const std::string name = text.substr(0, eq), value = text.substr(eq + 1);
  std::vector<std::string> free;
  for (const auto& p : source.params) {
    if (p.name == name && p.value)
      throw UserError(SourceLoc{},
                      fmt::format("--plant-param {}: '{}' is not a free parameter (the model file "
                                  "gives it the value {}); only free parameters can differ "
                                  "between plant and observer",
                                  name, name, to_string(*p.value)));
    if (p.name == name)
      return {&p, parse_real_number(value, fmt::format("--plant-param {}={}", name, value))};
    if (!p.value) free.push_back(p.name);
  }
  throw UserError(
      SourceLoc{},
      fmt::format("--plant-param {}: the model has no parameter '{}' "
                  "(its free parameters: {})",
                  name, name, free.empty() ? "none" : fmt::format("{}", fmt::join(free, ", "))));
}

// The plant's model and parameter values: the observer's values (its run-time defaults and the
// --param bindings), with the --plant-param assignments in their place. `note` lists the values
// that differ from the observer's.
struct PlantParameters {
  const Model* model;
  GiNaC::exmap values;
  std::string note;
};

// The observer's parameter values by name (symbols may differ between copies of a model).
std::map<std::string, GiNaC::numeric> observer_parameters(const Model& analysed,
                                                          const GiNaC::exmap& runtime) {
  std::map<std::string, GiNaC::numeric> by_name;
  for (const auto& p : analysed.params) {
    const Interval box = analysed.box(p.symbol);
    by_name[p.name] = p.value ? *p.value : (box.lo + box.hi) / 2;
  }
  for (const auto& [sym, v] : runtime)
    by_name[GiNaC::ex_to<GiNaC::symbol>(sym).get_name()] = GiNaC::ex_to<GiNaC::numeric>(v);
  return by_name;
}

std::string outside_box_note(const Model& source, const std::string& name,
                             const GiNaC::numeric& v) {
  const auto box = source.domain.find(name);
  if (box == source.domain.end() || (v >= box->second.lo && v <= box->second.hi)) return "";
  return fmt::format(", outside the box [{}, {}] the analysis holds on", to_string(box->second.lo),
                     to_string(box->second.hi));
}

// The --plant-param assignments, checked (names, values, repeats) against the model as read.
std::vector<std::pair<const Param*, GiNaC::numeric>> plant_assignments(
    const Model& source, const SimulationOptions& opt) {
  std::vector<std::pair<const Param*, GiNaC::numeric>> out;
  for (const auto& text : opt.plant_params) {
    out.push_back(plant_assignment(source, text));
    for (std::size_t i = 0; i + 1 < out.size(); ++i)
      if (out[i].first == out.back().first)
        throw UserError(SourceLoc{},
                        fmt::format("--plant-param {}: given twice", out.back().first->name));
  }
  return out;
}

const Model& plant_source(const Model& analysed, const SimulationOptions& opt) {
  return opt.unbound_model ? *opt.unbound_model : analysed;
}

PlantParameters plant_parameters(const Model& analysed, const SimulationOptions& opt,
                                 const GiNaC::exmap& runtime) {
  const Model& source = plant_source(analysed, opt);
  const auto observer = observer_parameters(analysed, runtime);
  auto plant = observer;
  std::vector<std::string> notes;
  for (const auto& [param, value] : plant_assignments(source, opt)) {
    plant[param->name] = value;
    notes.push_back(fmt::format("{} = {:g} (observer: {:g}{})", param->name, value.to_double(),
                                observer.at(param->name).to_double(),
                                outside_box_note(source, param->name, value)));
  }
  PlantParameters out{&source, {}, ""};
  if (!notes.empty()) out.note = fmt::format("plant parameters: {}", fmt::join(notes, "; "));
  for (const auto& p : source.params)
    if (!p.value) out.values[p.symbol] = plant.at(p.name);
  return out;
}

struct Recorder {
  SimulationResult& res;
  bool record(double t, const Vec& x, const Vec& xh, const char* observer_part) {
    if (!finite(x) || !finite(xh)) {
      res.diverged = fmt::format(
          "simulate: the {} left the finite numbers at t = {:g}; the run stopped there (the CSV "
          "and the plot end at t = {:g})",
          !finite(x) ? "plant" : observer_part, t, res.t.empty() ? 0.0 : res.t.back());
      return false;
    }
    res.t.push_back(t);
    res.x.push_back(x);
    res.xh.push_back(xh);
    return true;
  }
};

void run_state_observer(const Plant& plant, ProgramObserver& obs, const SimulationOptions& opt,
                        std::size_t steps, Recorder& rec) {
  const std::size_t n = opt.x0.size();
  Vec x = opt.x0;
  obs.reset(opt.xhat0);
  if (!rec.record(0, x, obs.estimate(), "observer")) return;
  for (std::size_t k = 0; k < steps; ++k) {
    const double t = static_cast<double>(k) * opt.dt;
    if (opt.sampling == Sampling::continuous) {
      // One ODE: [x; w]' = [f + g(x, u(t)); derivative(w, u(t), h(x))], in the sub-steps the
      // observer's own step would take over dt.
      const std::size_t parts = obs.substeps_over(opt.dt);
      const double h = opt.dt / static_cast<double>(parts);
      for (std::size_t i = 0; i < parts && obs.rejected().empty(); ++i) {
        Vec xw = concat(x, obs.state());
        rk4(
            [&](double tt, const Vec& v) {
              const Vec xv(v.begin(), v.begin() + static_cast<long>(n));
              const Vec wv(v.begin() + static_cast<long>(n), v.end());
              const Vec u = plant.inputs({tt});
              return concat(plant.field(concat(xv, u)),
                            obs.derivative(wv, u, plant.output(concat(xv, u))));
            },
            t + static_cast<double>(i) * h, h, xw);
        x.assign(xw.begin(), xw.begin() + static_cast<long>(n));
        obs.set_state(Vec(xw.begin() + static_cast<long>(n), xw.end()));
      }
    } else {
      obs.step(opt.dt, plant.inputs({t}), plant.y(t, x));
      rk4([&](double tt, const Vec& xv) { return plant.f(tt, xv); }, t, opt.dt, x);
    }
    if (!obs.rejected().empty()) {
      rec.res.diverged = fmt::format(
          "simulate: the observer rejected its step at t = {:g}: {}; the run stopped there", t,
          obs.rejected());
      return;
    }
    if (!rec.record(static_cast<double>(k + 1) * opt.dt, x, obs.estimate(), "observer")) return;
  }
}

// Discrete-time observers: the firmware step with u, y sampled at t_k (whatever --sampling).
void run_sampled_delay_observer(const Plant& plant, ProgramObserver& obs,
                                const SimulationOptions& opt, std::size_t steps, Recorder& rec) {
  Vec x = opt.x0;
  obs.reset(opt.xhat0);
  if (!rec.record(0, x, obs.estimate(), "observer")) return;
  for (std::size_t k = 0; k < steps; ++k) {
    const double t = static_cast<double>(k) * opt.dt;
    obs.step(opt.dt, plant.inputs({t}), plant.output(x));
    if (!obs.rejected().empty()) {
      rec.res.diverged = fmt::format(
          "simulate: the observer's fixed sample period differs from --dt {:g}", opt.dt);
      return;
    }
    rk4([&](double tt, const Vec& xv) { return plant.f(tt, xv); }, t, opt.dt, x);
    if (!rec.record(static_cast<double>(k + 1) * opt.dt, x, obs.estimate(), "observer")) return;
  }
}

void run_jets_observer(const Plant& plant, ProgramObserver& obs, const SimulationOptions& opt,
                       std::size_t steps, Recorder& rec) {
  Vec x = opt.x0;
  obs.reset(opt.xhat0, plant.y(0, opt.xhat0));
  if (!rec.record(0, x, obs.estimate(), "observer")) return;
  for (std::size_t k = 0; k < steps; ++k) {
    const double t = static_cast<double>(k) * opt.dt, t1 = static_cast<double>(k + 1) * opt.dt;
    rk4([&](double tt, const Vec& xv) { return plant.f(tt, xv); }, t, opt.dt, x);
    if (!finite(x)) {
      rec.record(t1, x, obs.estimate(), "observer");
      return;
    }
    obs.step(opt.dt, plant.inputs({t1}), plant.y(t1, x));
    if (!rec.record(t1, x, obs.estimate(), "observer")) return;
  }
}

GiNaC::exmap parameter_values(const ObserverSpec& s) {
  GiNaC::exmap at;
  for (const auto& p : s.params) at[p.symbol] = p.default_value;
  return at;
}

// The domain box of each state (Model::box: the declared one, else the default).
std::vector<StateBox> state_boxes(const Model& m) {
  std::vector<StateBox> out;
  for (const auto& x : m.states) {
    const Interval b = m.box(x);
    out.push_back({b.lo.to_double(), b.hi.to_double(), m.domain.count(x.get_name()) > 0});
  }
  return out;
}

// "the observer left the finite numbers at t = 0.7" out of the divergence diagnostic.
std::string stop_label(const std::string& diverged) {
  const std::string prefix = "simulate: ";
  std::string s =
      diverged.compare(0, prefix.size(), prefix) == 0 ? diverged.substr(prefix.size()) : diverged;
  return s.substr(0, s.find(';'));
}

std::string method_line(const SimulationResult& res) {
  return res.explanation.empty() ? fmt::format("observer: {}", res.method)
                                 : fmt::format("observer: {} ({})", res.method, res.explanation);
}

void render_outputs(const Model& m, const SimulationOptions& opt, const std::string& plant_note,
                    SimulationResult& res) {
  const std::size_t n = m.n();
  res.csv = csv_header(res.names);
  for (std::size_t i = 0; i < res.t.size(); ++i) {
    res.csv += fmt::format("{:.10g}", res.t[i]);
    for (double v : res.x[i]) res.csv += fmt::format(",{:.17g}", v);
    for (double v : res.xh[i]) res.csv += fmt::format(",{:.17g}", v);
    res.csv += "\n";
  }
  TrajectoryPlot plot{
      fmt::format("{}: {} observer{}, {} sampling, u = {}", m.name, res.method,
                  res.explanation.empty() ? "" : " (chosen by auto)",
                  opt.sampling == Sampling::continuous ? "continuous" : "zero-order hold",
                  opt.u_text),
      plant_note,
      res.names,
      res.t,
      res.x,
      res.xh,
      state_boxes(m),
      stop_label(res.diverged)};
  res.svg = render_svg(plot);
  // max over the states of |x - x_hat| at each sample: at the start, the end, and its peak
  // (a transient can exceed both).
  const auto error_at = [&](std::size_t s) {
    double e = 0;
    for (std::size_t k = 0; k < n; ++k) e = std::max(e, std::fabs(res.x[s][k] - res.xh[s][k]));
    return e;
  };
  std::size_t peak = 0;
  double peak_error = error_at(0);
  for (std::size_t s = 1; s < res.t.size(); ++s)
    if (const double e = error_at(s); e > peak_error) {
      peak = s;
      peak_error = e;
    }
  res.summary = method_line(res) + "\n";
  if (!plant_note.empty()) res.summary += plant_note + "\n";
  res.summary += fmt::format(
      "{} steps of {:g}: max |x - x_hat| {:.3e} at t = 0, {:.3e} at t = {:g} (peak {:.3e} at t "
      "= {:g})",
      res.t.size() - 1, opt.dt, error_at(0), error_at(res.t.size() - 1), res.t.back(), peak_error,
      res.t[peak]);
}

}  // namespace

std::optional<SafePeriod> sampled_safe_period(const Analysis& a, const ObserverSpec& spec) {
  const StepProgram program = lower(spec);
  const op::Rk4* rk4_op = program.find<op::Rk4>();
  if (!rk4_op || rk4_op->field.guarded || !rk4_op->field.held.empty()) return std::nullopt;
  const Model& m = a.model;
  const std::size_t S = 64;
  static const unsigned primes[] = {2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37, 41, 43, 47};
  const GiNaC::exmap params = parameter_values(spec);
  SpecFunctions fn(spec, params);
  ExVec h = m.measured_outputs();
  for (auto& e : h) e = e.subs(params);
  std::vector<std::string> xu = names_of(m.states);
  for (const auto& u : m.inputs) xu.push_back(u.get_name());
  const NumericFunction output(h, xu);
  SafePeriod out;
  for (std::size_t i = 0; i < S; ++i) {
    Vec x, u;
    std::size_t k = 0;
    for (const auto& sym : m.states) {
      const Interval b = m.box(sym);
      x.push_back(b.lo.to_double() + (b.hi - b.lo).to_double() * halton_point(i, primes[k++ % 15]));
    }
    for (const auto& sym : m.inputs) {
      const Interval b = m.box(sym);
      u.push_back(b.lo.to_double() + (b.hi - b.lo).to_double() * halton_point(i, primes[k++ % 15]));
    }
    const Vec y = output(concat(x, u));
    const Vec w = program.init.empty() ? x : fn(program.init)(x);
    const auto dim = static_cast<Eigen::Index>(w.size());
    Eigen::MatrixXd J(dim, dim);
    for (Eigen::Index j = 0; j < dim; ++j) {
      const double step = 1e-6 * std::max(1.0, std::fabs(w[static_cast<std::size_t>(j)]));
      Vec wp = w, wm = w;
      wp[static_cast<std::size_t>(j)] += step;
      wm[static_cast<std::size_t>(j)] -= step;
      const Vec fp = fn(rk4_op->field.rhs)(concat(concat(wp, u), y));
      const Vec fm = fn(rk4_op->field.rhs)(concat(concat(wm, u), y));
      for (Eigen::Index r = 0; r < dim; ++r)
        J(r, j) = (fp[static_cast<std::size_t>(r)] - fm[static_cast<std::size_t>(r)]) / (2 * step);
    }
    if (!J.allFinite()) continue;
    const Eigen::VectorXcd ev = Eigen::EigenSolver<Eigen::MatrixXd>(J, false).eigenvalues();
    for (Eigen::Index r = 0; r < ev.size(); ++r) out.rho = std::max(out.rho, std::abs(ev(r)));
    ++out.samples;
  }
  if (out.samples == 0 || !(out.rho > 0) || !std::isfinite(out.rho)) return std::nullopt;
  out.period = kRk4StabilityRadius / out.rho;
  return out;
}

SimulationResult run_closed_loop(const Analysis& a, const ObserverSpec& spec,
                                 const SimulationOptions& opt, std::string* plant_note) {
  const Model& m = a.model;
  const std::size_t steps = step_count(opt, m.n());
  const GiNaC::exmap params = parameter_values(spec);
  const PlantParameters pp = plant_parameters(m, opt, params);
  const Plant plant = make_plant(*pp.model, opt.u_text, pp.values);
  if (plant_note) *plant_note = pp.note;
  SimulationResult res;
  res.method = spec.method;
  res.names = names_of(m.states);
  Recorder rec{res};
  // The run's timing follows the program: differentiators take the sample at the end of the
  // interval, a fixed sample period takes the samples at its start, anything else runs as the
  // firmware step or (continuous sampling) through the vector field.
  ProgramObserver obs(spec, params, opt, m.m(), m.p());
  if (obs.program().has<op::JetUpdate>())
    run_jets_observer(plant, obs, opt, steps, rec);
  else if (obs.program().has<op::SampleGuard>())
    run_sampled_delay_observer(plant, obs, opt, steps, rec);
  else
    run_state_observer(plant, obs, opt, steps, rec);
  return res;
}

SimulationResult simulate(const Analysis& a, const SimulationOptions& opt) {
  const Model& m = a.model;
  step_count(opt, m.n());                        // bad --x0 / --dt fail before any work
  plant_assignments(plant_source(m, opt), opt);  // a bad --plant-param fails before any work
  // A design with a fixed sample period gets --dt unless it was given.
  DesignOptions design = opt.design;
  for (const auto& d : design_registry())
    for (const auto& o : d.options)
      if (o.name == "sample-period" && !design.find(o.name))
        design.values[o.name] = fmt::format("{:.17g}", opt.dt);
  std::string explanation;
  const BuiltDesign built = choose_and_build(a, opt.method, design, explanation);
  std::string plant_note;
  SimulationResult res = run_closed_loop(a, built.spec, opt, &plant_note);
  res.method = built.method;
  res.explanation = explanation;
  if (res.t.empty())
    throw UserError(SourceLoc{}, res.diverged.empty() ? "simulate: nothing recorded"
                                                      : res.diverged + " before the first sample");
  render_outputs(m, opt, plant_note, res);
  return res;
}

}  // namespace obsynth
