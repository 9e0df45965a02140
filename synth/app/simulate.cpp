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

Vec axpy(const Vec& x, double a, const Vec& k) {
  Vec r(x);
  for (std::size_t i = 0; i < r.size(); ++i) r[i] += a * k[i];
  return r;
}

// Classical RK4 on a vector field of arbitrary dimension (the scheme of rk4_step).
template <class F>
void rk4(F&& rhs, double t, double dt, Vec& x) {
  const Vec k1 = rhs(t, x);
  const Vec k2 = rhs(t + dt / 2, axpy(x, dt / 2, k1));
  const Vec k3 = rhs(t + dt / 2, axpy(x, dt / 2, k2));
  const Vec k4 = rhs(t + dt, axpy(x, dt, k3));
  for (std::size_t i = 0; i < x.size(); ++i)
    x[i] += dt / 6 * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i]);
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

// Newton on T(x) = z with (dT/dx)^-1 given, as the runtime does.
Vec newton(const NumericFunction& T, const NumericFunction& frame, const Vec& z, Vec x,
           int iterations, double tol) {
  const std::size_t n = z.size();
  for (int it = 0; it < iterations; ++it) {
    const Vec Tx = T(x);
    double res = 0;
    Vec r(n);
    for (std::size_t i = 0; i < n; ++i) {
      r[i] = Tx[i] - z[i];
      res = std::max(res, std::fabs(r[i]));
    }
    if (res <= tol) break;
    const Vec tau = frame(x);  // column-major: tau_k = columns
    for (std::size_t i = 0; i < n; ++i) {
      double d = 0;
      for (std::size_t k = 0; k < n; ++k) d += tau[k * n + i] * r[k];
      x[i] -= d;
    }
  }
  return x;
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

// One observer run: its state w, estimate xh, and how both advance.
class SpecObserver {
 public:
  SpecObserver(const ObserverSpec& s, const GiNaC::exmap& params, const SimulationOptions& o)
      : s_(s), fn_(s, params), o_(o) {}

  void reset(const Vec& xh0) {
    xh_ = xh0;
    w_ = s_.init == InitKind::function ? fn_(s_.roles.init)(xh0) : xh0;
  }
  // d/dt w at (w, u, y): the generated derivative(). A failed gain solve sets `rejected`.
  Vec derivative(const Vec& w, const Vec& u, const Vec& y) {
    if (s_.update != UpdateKind::ode)
      return fn_(s_.roles.rhs)(concat(w, fn_(s_.roles.step_constant)(concat(u, y))));
    Vec dw = fn_(s_.roles.rhs)(concat(concat(w, u), y));
    if (s_.correction && !add_correction(*s_.correction, w, u, y, dw))
      rejected_ = "the gain solve failed (" + s_.correction->singular_doc + ")";
    return dw;
  }
  // The firmware step with u, y held over dt.
  void step(double dt, const Vec& u, const Vec& y) {
    if (s_.update == UpdateKind::linear_exact && !s_.rk4_for_linear) {
      if (!(dt == dt_)) {
        if (!exact_discretisation(s_, dt, E_, Gamma_)) {
          rejected_ = "the exact discretisation failed (a bad dt or a non-finite e^{A dt})";
          return;
        }
        dt_ = dt;
      }
      // w + (E w + Gamma c), the increment added once (as the C step and the float runtime)
      const Vec c = fn_(s_.roles.step_constant)(concat(u, y));
      const std::size_t n = w_.size();
      Vec next(n);
      for (std::size_t i = 0; i < n; ++i) {
        double acc = 0;
        for (std::size_t j = 0; j < n; ++j) acc += E_[i * n + j] * w_[j] + Gamma_[i * n + j] * c[j];
        next[i] = w_[i] + acc;
      }
      w_ = next;
    } else {
      const Vec before = w_;
      // Equal RK4 sub-steps no longer than the design's max_substep, as the generated step.
      const std::size_t steps = substeps(dt);
      for (std::size_t k = 0; k < steps; ++k)
        rk4([&](double, const Vec& w) { return derivative(w, u, y); }, 0,
            dt / static_cast<double>(steps), w_);
      check_blocks();
      if (!rejected_.empty()) w_ = before;  // the generated step keeps its state too
    }
    update_estimate();
  }
  // ceil(dt / max_substep), 1..4096 (ObserverSpec::max_substep; 1 when it is 0).
  std::size_t substeps(double dt) const {
    if (!(s_.max_substep > 0)) return 1;
    const double ratio = dt / s_.max_substep.to_double();
    if (!(ratio > 1)) return 1;
    return ratio >= 4096 ? 4096 : static_cast<std::size_t>(std::ceil(ratio));
  }
  // Why the last step or derivative was rejected (empty: it was not).
  const std::string& rejected() const { return rejected_; }
  void set_state(const Vec& w) {
    w_ = w;
    check_blocks();
    update_estimate();
  }
  const Vec& state() const { return w_; }
  const Vec& estimate() const { return xh_; }

 private:
  void update_estimate() {
    switch (s_.estimate) {
      case EstimateKind::identity:
        xh_ = w_;
        break;
      case EstimateKind::function:
        xh_ = fn_(s_.roles.estimate)(w_);
        break;
      case EstimateKind::newton:
        xh_ = newton(fn_(s_.roles.newton_map), fn_(s_.roles.newton_inverse_jacobian), w_, xh_,
                     s_.newton_iterations, o_.newton_tolerance);
        break;
    }
  }
  // Symmetric blocks that must stay positive definite (Cholesky, as the generated step).
  void check_blocks() {
    for (const auto& b : s_.symmetric_blocks) {
      if (!b.keep_positive_definite) continue;
      Vec work(b.dim * b.dim + b.dim);
      if (!c_double::obsynth_packed_positive_definite(w_.data(), static_cast<int>(b.offset),
                                                      static_cast<int>(b.dim), work.data()))
        rejected_ = b.name + " is no longer positive definite";
    }
  }
  // dw[target..] += M^-1 v by the generated code's factorisation (the runtime's kernels).
  bool add_correction(const SolveCorrection& k, const Vec& w, const Vec& u, const Vec& y, Vec& dw) {
    const std::size_t d = k.dim;
    Vec M(d * d);  // row-major
    if (!k.matrix_function.empty()) {
      const Vec mv = fn_(k.matrix_function)(concat(w, u));  // column-major
      for (std::size_t r = 0; r < d; ++r)
        for (std::size_t c = 0; c < d; ++c) M[r * d + c] = mv[c * d + r];
    } else {
      for (const auto& b : s_.symmetric_blocks)
        if (b.name == k.matrix_block)
          c_double::obsynth_unpack_symmetric(w.data(), static_cast<int>(b.offset),
                                             static_cast<int>(b.dim), M.data());
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

  const ObserverSpec& s_;
  SpecFunctions fn_;
  const SimulationOptions& o_;
  Vec w_, xh_;
  Vec E_, Gamma_;  // row-major, for dt_
  double dt_ = 0;
  std::string rejected_;
};

// The jets observer (perfect): differentiators for y and u, then reconstruct and estimate.
class JetsObserver {
 public:
  JetsObserver(const ObserverSpec& s, const GiNaC::exmap& params, const SimulationOptions& o,
               std::size_t inputs, std::size_t outputs)
      : s_(s), fn_(s, params), o_(o) {
    for (std::size_t q = 0; q < outputs; ++q)
      y_.push_back(make_jet(s.y_jet_order, s.default_epsilon));
    for (std::size_t j = 0; j < inputs; ++j)
      u_.push_back(make_jet(s.u_jet_order, s.default_epsilon));
  }
  void reset(const Vec& xh0, const Vec& y0) {
    xh_ = xh0;
    for (std::size_t q = 0; q < y_.size(); ++q) y_[q]->reset(y0[q]);
    for (auto& d : u_) d->reset(0);
  }
  void update(double dt, const Vec& u, const Vec& y) {
    for (std::size_t q = 0; q < y_.size(); ++q) y_[q]->update(dt, y[q]);
    for (std::size_t j = 0; j < u_.size(); ++j) u_[j]->update(dt, u[j]);
    // Arguments (yj, uj): yj output by output; uj column-major (order k outer, input j inner).
    Vec in;
    for (const auto& d : y_) {
      const Vec jet = d->jet();
      in.insert(in.end(), jet.begin(), jet.end());
    }
    const std::size_t orders = s_.u_jet_order + 1;
    for (std::size_t k = 0; k < orders; ++k)
      for (const auto& d : u_) in.push_back(d->jet()[k]);
    const Vec r = fn_(s_.roles.reconstruct)(in);
    xh_ = s_.estimate == EstimateKind::newton
              ? newton(fn_(s_.roles.newton_map), fn_(s_.roles.newton_inverse_jacobian), r, xh_,
                       s_.newton_iterations, o_.newton_tolerance)
              : r;
  }
  const Vec& estimate() const { return xh_; }

 private:
  const ObserverSpec& s_;
  SpecFunctions fn_;
  const SimulationOptions& o_;
  std::vector<std::unique_ptr<Jet>> y_, u_;
  Vec xh_;
};

// ---- UpdateKind::sampled_delay (spec.hpp SampledDelay): filter bank, delay line, kernel
// inverse over the tables, in double, in the order the generated step uses.
class SampledDelayObserver {
 public:
  explicit SampledDelayObserver(const ObserverSpec& s)
      : d_(*s.sampled_delay),
        decay_(s.table(d_.decay_table)->values),
        gain_(s.table(d_.gain_table)->values),
        delay_(s.table(d_.delay_table)->values),
        metric_(s.table(d_.metric_table)->values),
        map_(s.table(d_.map_table)->values),
        slope_(d_.slope_table.empty() ? map_ : s.table(d_.slope_table)->values) {}
  void reset(const Vec& xh0) {
    xh_ = xh0;
    ring_.assign((d_.delay_steps + 1) * d_.filters, 0.0);
    u_ring_.assign(d_.delay_steps + 1, 0.0);
    head_ = 0;
    filled_ = 0;
  }
  // False when dt is not the design's sample period.
  bool step(double dt, const Vec& u, const Vec& y) {
    if (!(std::fabs(dt - d_.sample_period) <= 1e-6 * d_.sample_period)) return false;
    const std::size_t pz = d_.filters, slots = d_.delay_steps + 1;
    const std::size_t next = (head_ + 1) % slots;
    for (std::size_t j = 0; j < pz; ++j)
      ring_[next * pz + j] = decay_[j] * ring_[head_ * pz + j] + gain_[j] * y[j % d_.outputs];
    u_ring_[next] = d_.levels > 1 ? u[d_.input_index] : 0.0;
    head_ = next;
    if (filled_ < d_.delay_steps) ++filled_;
    if (filled_ < d_.delay_steps) return true;
    const std::size_t old = (head_ + 1) % slots;  // D steps ago
    std::size_t level = 0;
    double frac = 0;   // level_interpolate: the weight of table level + 1
    double slope = 0;  // slope_table: du/dt fitted over the window
    if (d_.levels > 1) {
      double v = u[d_.input_index];
      if (d_.level_window_mean) {
        double acc = 0;
        for (std::size_t k = 0; k < slots; ++k)
          if (k != old) acc += u_ring_[k];
        v = acc / static_cast<double>(d_.delay_steps);
        if (!d_.slope_table.empty()) slope = window_slope(v, dt);
      }
      if (d_.level_interpolate) {
        const double top = static_cast<double>(d_.levels - 1);
        const double r = std::clamp((v - d_.level_lo) / d_.level_step, 0.0, top);
        level = std::min(static_cast<std::size_t>(std::floor(r)), d_.levels - 2);
        frac = r - static_cast<double>(level);
      } else {
        v = std::floor((v - d_.level_lo) / d_.level_step + (d_.level_nearest ? 0.5 : 0.0));
        level = v <= 0                                    ? 0
                : v >= static_cast<double>(d_.levels - 1) ? d_.levels - 1
                                                          : static_cast<std::size_t>(v);
      }
    }
    Vec raw(pz), eta(pz, 0.0);
    for (std::size_t j = 0; j < pz; ++j)
      raw[j] = ring_[head_ * pz + j] - delay_[j] * ring_[old * pz + j];
    for (std::size_t j = 0; j < pz; ++j)
      for (std::size_t k = 0; k < pz; ++k) eta[j] += metric_[j * pz + k] * raw[k];
    const std::size_t n = d_.grid_count.size(), N = d_.points();
    std::vector<std::size_t> idx(n, 0);
    Vec sx(n, 0.0);
    double sw = 0;
    const double* q = map_.data() + level * N * pz;
    // The next level's table (read only when interpolating, then level + 1 < levels).
    const double* q1 = d_.level_interpolate && d_.levels > 1 ? q + N * pz : q;
    const double* dq = slope_.data() + level * N * pz;  // read only with a slope table
    const double* dq1 = d_.level_interpolate && d_.levels > 1 ? dq + N * pz : dq;
    for (std::size_t i = 0; i < N; ++i, q += pz, q1 += pz, dq += pz, dq1 += pz) {
      double d2 = 0;
      for (std::size_t j = 0; j < pz; ++j) {
        double e = q[j] + frac * (q1[j] - q[j]) - eta[j];
        if (slope != 0) e += slope * (dq[j] + frac * (dq1[j] - dq[j]));
        d2 += e * e;
      }
      const double b = 1 / (d_.epsilon + std::sqrt(d2));
      double w = b;
      for (int k = 1; k < d_.weight_power; ++k) w *= b;
      sw += w;
      for (std::size_t s = 0; s < n; ++s)
        sx[s] += w * (d_.grid_lo[s] + d_.grid_step[s] * static_cast<double>(idx[s]));
      for (std::size_t s = n; s-- > 0;) {
        if (++idx[s] < d_.grid_count[s]) break;
        idx[s] = 0;
      }
    }
    for (std::size_t s = 0; s < n; ++s) xh_[s] = sx[s] / sw;
    return true;
  }
  const Vec& estimate() const { return xh_; }

 private:
  // Least-squares slope (du/dt) of the window's D input samples, whose mean is v (spec.hpp).
  double window_slope(double v, double dt) const {
    const std::size_t D = d_.delay_steps, slots = D + 1;
    const double abar = static_cast<double>(D - 1) / 2;
    double sxy = 0, sxx = 0;
    for (std::size_t a = 0; a < D; ++a) {  // a = 0: this step's sample
      const double da = static_cast<double>(a) - abar;
      sxy += da * (u_ring_[(head_ + slots - a) % slots] - v);
      sxx += da * da;
    }
    return sxx > 0 ? -sxy / (dt * sxx) : 0.0;
  }
  const SampledDelay& d_;
  const Vec &decay_, &gain_, &delay_, &metric_, &map_, &slope_;
  Vec ring_, u_ring_, xh_;
  std::size_t head_ = 0, filled_ = 0;
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

void run_state_observer(const Plant& plant, SpecObserver& obs, const SimulationOptions& opt,
                        std::size_t steps, Recorder& rec) {
  const std::size_t n = opt.x0.size();
  Vec x = opt.x0;
  obs.reset(opt.xhat0);
  if (!rec.record(0, x, obs.estimate(), "observer")) return;
  for (std::size_t k = 0; k < steps; ++k) {
    const double t = static_cast<double>(k) * opt.dt;
    if (opt.sampling == Sampling::continuous) {
      // One ODE: [x; w]' = [f + g(x, u(t)); derivative(w, u(t), h(x))].
      Vec xw = concat(x, obs.state());
      rk4(
          [&](double tt, const Vec& v) {
            const Vec xv(v.begin(), v.begin() + static_cast<long>(n));
            const Vec wv(v.begin() + static_cast<long>(n), v.end());
            const Vec u = plant.inputs({tt});
            return concat(plant.field(concat(xv, u)),
                          obs.derivative(wv, u, plant.output(concat(xv, u))));
          },
          t, opt.dt, xw);
      x.assign(xw.begin(), xw.begin() + static_cast<long>(n));
      obs.set_state(Vec(xw.begin() + static_cast<long>(n), xw.end()));
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
void run_sampled_delay_observer(const Plant& plant, SampledDelayObserver& obs,
                                const SimulationOptions& opt, std::size_t steps, Recorder& rec) {
  Vec x = opt.x0;
  obs.reset(opt.xhat0);
  if (!rec.record(0, x, obs.estimate(), "observer")) return;
  for (std::size_t k = 0; k < steps; ++k) {
    const double t = static_cast<double>(k) * opt.dt;
    if (!obs.step(opt.dt, plant.inputs({t}), plant.output(x))) {
      rec.res.diverged = fmt::format(
          "simulate: the observer's fixed sample period differs from --dt {:g}", opt.dt);
      return;
    }
    rk4([&](double tt, const Vec& xv) { return plant.f(tt, xv); }, t, opt.dt, x);
    if (!rec.record(static_cast<double>(k + 1) * opt.dt, x, obs.estimate(), "observer")) return;
  }
}

void run_jets_observer(const Plant& plant, JetsObserver& obs, const SimulationOptions& opt,
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
    obs.update(opt.dt, plant.inputs({t1}), plant.y(t1, x));
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
  double e0 = 0, e1 = 0;
  for (std::size_t k = 0; k < n; ++k) {
    e0 = std::max(e0, std::fabs(res.x.front()[k] - res.xh.front()[k]));
    e1 = std::max(e1, std::fabs(res.x.back()[k] - res.xh.back()[k]));
  }
  res.summary = method_line(res) + "\n";
  if (!plant_note.empty()) res.summary += plant_note + "\n";
  res.summary +=
      fmt::format("{} steps of {:g}: max |x - x_hat| {:.3e} at t = 0, {:.3e} at t = {:g}",
                  res.t.size() - 1, opt.dt, e0, e1, res.t.back());
}

}  // namespace

std::optional<SafePeriod> sampled_safe_period(const Analysis& a, const ObserverSpec& spec) {
  if (spec.update != UpdateKind::ode || spec.correction || !spec.symmetric_blocks.empty())
    return std::nullopt;
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
    const Vec w = spec.init == InitKind::function ? fn(spec.roles.init)(x) : x;
    const auto dim = static_cast<Eigen::Index>(w.size());
    Eigen::MatrixXd J(dim, dim);
    for (Eigen::Index j = 0; j < dim; ++j) {
      const double step = 1e-6 * std::max(1.0, std::fabs(w[static_cast<std::size_t>(j)]));
      Vec wp = w, wm = w;
      wp[static_cast<std::size_t>(j)] += step;
      wm[static_cast<std::size_t>(j)] -= step;
      const Vec fp = fn(spec.roles.rhs)(concat(concat(wp, u), y));
      const Vec fm = fn(spec.roles.rhs)(concat(concat(wm, u), y));
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
  if (spec.update == UpdateKind::jets) {
    JetsObserver obs(spec, params, opt, m.m(), m.p());
    run_jets_observer(plant, obs, opt, steps, rec);
  } else if (spec.update == UpdateKind::sampled_delay) {
    SampledDelayObserver obs(spec);
    run_sampled_delay_observer(plant, obs, opt, steps, rec);
  } else {
    SpecObserver obs(spec, params, opt);
    run_state_observer(plant, obs, opt, steps, rec);
  }
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
