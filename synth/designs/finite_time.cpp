#include "designs/finite_time.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <optional>

#include <Eigen/Dense>

#include "certify/sampling.hpp"
#include "designs/options.hpp"
#include "symbolic/dag.hpp"
#include "symbolic/expr_print.hpp"

namespace obsynth {

namespace {

using Array = Eigen::ArrayXd;

// ---- vectorised evaluation of model expressions over many points ------------------------

// The model's expressions evaluated elementwise over arrays (one entry per grid point), through
// the same DAG the emitters print from. Used only to tabulate q; the observer reads the tables.
class ArrayFunction {
 public:
  ArrayFunction(const ExVec& outputs, const std::vector<std::string>& inputs) {
    for (const auto& e : outputs) out_.push_back(dag_.add(e));
    for (std::size_t i = 0; i < inputs.size(); ++i) input_[inputs[i]] = i;
  }
  std::vector<Array> operator()(const std::vector<Array>& in) const {
    const Eigen::Index len = in.empty() ? 1 : in[0].size();
    std::vector<Array> v(dag_.size());
    for (std::size_t id = 0; id < dag_.size(); ++id)
      v[id] = node_value(dag_.node(static_cast<int>(id)), v, in, len);
    std::vector<Array> out;
    for (int id : out_) out.push_back(v[static_cast<std::size_t>(id)]);
    return out;
  }

 private:
  // One node over the arrays, its arguments' values in v (the DAG is topologically ordered).
  Array node_value(const Node& n, const std::vector<Array>& v, const std::vector<Array>& in,
                   Eigen::Index len) const {
    auto arg = [&](std::size_t i) -> const Array& {
      return v[static_cast<std::size_t>(n.args[i])];
    };
    Array r;
    switch (n.op) {
      case NodeOp::constant:
        r = Array::Constant(len, n.value.to_double());
        break;
      case NodeOp::variable: {
        auto it = input_.find(n.name);
        OBSYNTH_ASSERT(it != input_.end(), "finite-time: unbound symbol " + n.name);
        r = in[it->second];
        break;
      }
      case NodeOp::add:
        r = arg(0);
        for (std::size_t i = 1; i < n.args.size(); ++i) r += arg(i);
        break;
      case NodeOp::mul:
        r = arg(0);
        for (std::size_t i = 1; i < n.args.size(); ++i) r *= arg(i);
        break;
      case NodeOp::div:
        r = arg(0) / arg(1);
        break;
      case NodeOp::neg:
        r = -arg(0);
        break;
      case NodeOp::pow_int:
        r = arg(0);
        for (long k = 1; k < n.exponent; ++k) r *= arg(0);
        break;
      case NodeOp::sqrt:
        r = arg(0).sqrt();
        break;
      case NodeOp::pow_real:
        r = arg(0).pow(n.value.to_double());
        break;
      case NodeOp::call:
        r = call_value(n.name, arg(0));
        break;
    }
    return r;
  }

  // A function call node elementwise; the DAG admits only these functions here.
  static Array call_value(const std::string& name, const Array& a) {
    Array r;
    if (name == "sin")
      r = a.sin();
    else if (name == "cos")
      r = a.cos();
    else if (name == "tan")
      r = a.tan();
    else if (name == "exp")
      r = a.exp();
    else if (name == "log")
      r = a.log();
    else if (name == "tanh")
      r = a.tanh();
    else if (name == "atan")
      r = a.atan();
    else if (name == "atanh")
      r = a.unaryExpr([](double q) { return std::atanh(q); });
    else
      OBSYNTH_ASSERT(false, "finite-time: unsupported function " + name);
    return r;
  }

  Dag dag_;
  std::vector<int> out_;
  std::map<std::string, std::size_t> input_;
};

// ---- design choices ---------------------------------------------------------------------

struct Choices {
  double T = 1, dt = 0.01;
  std::size_t D = 100;
  std::vector<double> lambda;
  std::vector<double> lo, step;
  std::vector<std::size_t> count;
  double level_lo = 0, level_step = 1;
  std::size_t levels = 1;
  double eps = 0;
  bool eps_given = false;
  int power = 1;
  std::size_t backward_steps = 200;
  std::size_t bound_samples = 300;
  std::size_t outputs = 1;  // p: filter j is fed y_(j mod p)
  bool whiten = true;
  bool nearest = true, window_mean = true, interpolate = true;
  double rate = 0;  // --input-rate: |u'| of the ramps the sampled bound covers
  bool rate_given = false;
  // --input-slope correct: a second table per level, dq/du' (the map's sensitivity to a ramp of
  // the input over the window), applied with the slope the runtime fits to the window's inputs.
  bool slope = false;
  std::vector<std::string> notes;  // how defaults were chosen
  // What the user fixed; the search (search_design) chooses the rest.
  bool window_given = false, dt_given = false, poles_given = false, grid_given = false,
       levels_given = false, power_given = false;
  double target = 0.05;                  // --error-target: fraction of each state's box width
  std::size_t budget_bytes = 256 << 10;  // --table-memory, counted at 4 bytes an entry (float)
  std::vector<double> width;             // each state's box width
  std::size_t candidates = 0;            // settings the search evaluated
  double input_hi = 0;                   // the input's box is [level_lo, input_hi]
};

double dbl(const GiNaC::numeric& q) {
  return q.to_double();
}

UserError option_error(const std::string& text) {
  return UserError(SourceLoc{}, text);
}

std::size_t count_for(double lo, double hi, double step, const std::string& what) {
  const double k = (hi - lo) / step;
  const double r = std::round(k);
  if (std::fabs(k - r) > 1e-6 * std::max(1.0, k))
    throw option_error(
        fmt::format("{}: the step {} does not divide [{}, {}] (ratio {})", what, step, lo, hi, k));
  return static_cast<std::size_t>(r) + 1;
}

// A window the search proposes: a whole number of given sample periods (at least one), or 100
// samples when no sample period was given.
void set_window(Choices& c, double T) {
  if (c.dt_given) {
    c.D = std::max<std::size_t>(1, static_cast<std::size_t>(std::llround(T / c.dt)));
    c.T = c.dt * static_cast<double>(c.D);
  } else {
    c.T = T;
    c.dt = T / 100;
    c.D = 100;
  }
}

// The window T and the sample period dt: the delay line holds D = T / dt samples, a whole
// number. Without --window the search chooses T (search_window).
void choose_window(const DesignOptions& o, Choices& c) {
  if (const auto dt = real_option(o, "sample-period")) {
    c.dt = dbl(*dt);
    c.dt_given = true;
    if (!(c.dt > 0)) throw option_error("--sample-period must be positive");
  }
  const auto T = real_option(o, "window");
  if (!T) return;
  c.T = dbl(*T);
  c.window_given = true;
  if (!(c.T > 0)) throw option_error("--window: T must be positive");
  if (!c.dt_given) c.dt = c.T / 100;
  const double D = c.T / c.dt;
  c.D = static_cast<std::size_t>(std::llround(D));
  if (c.D < 1 || std::fabs(D - static_cast<double>(c.D)) > 1e-6 * D)
    throw option_error(fmt::format(
        "--window {} is not a whole number of sample periods {} (ratio {}): the delay line "
        "has fixed length",
        c.T, c.dt, D));
  if (c.D > 1000000) throw option_error("the delay line would exceed 10^6 samples");
}

// Without --filter-poles: 2n + 1 filters (Kreisselmeier-Engel: generically enough for
// injectivity), spread geometrically from -0.2/T to -20/T.
void default_poles(Choices& c, std::size_t n) {
  if (c.poles_given) return;
  const std::size_t k = 2 * n + 1;
  c.lambda.clear();
  for (std::size_t i = 0; i < k; ++i)
    c.lambda.push_back(-0.2 / c.T *
                       std::pow(100.0, static_cast<double>(i) / static_cast<double>(k - 1)));
}

// The filter poles (the diagonal A), distinct and negative.
void choose_filters(const DesignOptions& o, Choices& c) {
  for (const auto& q : real_list_option(o, "filter-poles")) {
    if (!q.is_negative())
      throw option_error(fmt::format("--filter-poles: {} is not negative", to_string(q)));
    c.lambda.push_back(dbl(q));
  }
  c.poles_given = !c.lambda.empty();
  for (std::size_t i = 0; i < c.lambda.size(); ++i)
    for (std::size_t j = 0; j < i; ++j)
      if (c.lambda[i] == c.lambda[j])
        throw option_error(
            "--filter-poles: the eigenvalues must be distinct (A diagonal, "
            "(A, b) controllable)");
}

// Table entries of a setting: the maps q_k, the filter tables and the metric.
std::size_t table_entries(const Choices& c) {
  std::size_t N = 1;
  for (auto k : c.count) N *= k;
  const std::size_t pz = c.lambda.size();
  return (c.slope ? 2 : 1) * c.levels * N * pz + 3 * pz + pz * pz;
}

// Without --grid-step: the same number of points per state, as many as the table-memory budget
// holds (4 bytes an entry). False when not even 3 per state fit.
bool fill_grid(Choices& c) {
  if (c.grid_given) return true;
  const std::size_t n = c.lo.size(), pz = c.lambda.size();
  const double entries = static_cast<double>(c.budget_bytes / 4) - 3.0 * pz - 1.0 * pz * pz;
  const double points = entries / static_cast<double>((c.slope ? 2 : 1) * c.levels * pz);
  std::size_t per_axis = points >= 1 ? static_cast<std::size_t>(std::floor(
                                           std::pow(points, 1.0 / static_cast<double>(n)) + 1e-9))
                                     : 0;
  while (per_axis >= 3 && std::pow(static_cast<double>(per_axis), static_cast<double>(n)) > points)
    --per_axis;
  if (per_axis < 3) return false;
  for (std::size_t s = 0; s < n; ++s) {
    c.count[s] = per_axis;
    c.step[s] = c.width[s] / static_cast<double>(per_axis - 1);
  }
  return true;
}

// The state grid over the domain box: --grid-step, else filled from the memory budget.
void choose_grid(const DesignOptions& o, const Model& m, Choices& c) {
  const auto steps = real_list_option(o, "grid-step");
  if (steps.size() > 1 && steps.size() != m.n())
    throw option_error(fmt::format("--grid-step: give one step or one per state ({}), got {}",
                                   m.n(), steps.size()));
  c.grid_given = !steps.empty();
  for (std::size_t s = 0; s < m.n(); ++s) {
    const Interval b = m.box(m.states[s]);
    const double lo = dbl(b.lo), hi = dbl(b.hi);
    c.lo.push_back(lo);
    c.width.push_back(hi - lo);
    if (steps.empty()) {
      c.count.push_back(3);
      c.step.push_back((hi - lo) / 2);
    } else {
      const double h = dbl(steps.size() == 1 ? steps[0] : steps[s]);
      if (!(h > 0)) throw option_error("--grid-step must be positive");
      c.step.push_back(h);
      c.count.push_back(count_for(lo, hi, h, "--grid-step for " + m.states[s].get_name()));
    }
  }
}

// The input levels (one table each) over the input's box: --input-step, else 11 levels.
void choose_levels(const DesignOptions& o, const Model& m, Choices& c) {
  if (m.m() != 1) return;
  const Interval b = m.box(m.inputs[0]);
  c.level_lo = dbl(b.lo);
  const double hi = dbl(b.hi);
  if (const auto mu = real_option(o, "input-step")) {
    c.level_step = dbl(*mu);
    c.levels_given = true;
    if (!(c.level_step > 0)) throw option_error("--input-step must be positive");
  } else {
    c.level_step = hi > c.level_lo ? (hi - c.level_lo) / 10 : 1;
  }
  c.input_hi = hi;
  c.levels = hi > c.level_lo ? count_for(c.level_lo, hi, c.level_step, "--input-step") : 1;
}

// The kernel (epsilon, weight power, metric), the level rule and the backward steps.
void choose_kernel(const DesignOptions& o, Choices& c) {
  if (const auto e = real_option(o, "kernel-epsilon")) {
    c.eps = dbl(*e);
    c.eps_given = true;
    if (!(c.eps > 0)) throw option_error("--kernel-epsilon must be positive");
  }
  if (const auto p = real_option(o, "weight-power")) {
    if (!p->is_pos_integer() || *p > 16)
      throw option_error("--weight-power: an integer 1..16 (1: eq. 15, n + 2: eq. 13)");
    c.power = static_cast<int>(p->to_int());
    c.power_given = true;
  }
  // The level rule. Seed 004 switches the inverse with the sampled input, Q(., u(t)) = Q_k for
  // u_k <= u(t_i) < u_k+1 (sample-floor), and reports peaks where the inverse switches ("due to
  // the inverse map transitions that match the control switching events", section IV), which
  // "can be reduced ... by refining the control mesh". The default, window-interpolate, does
  // that refinement without more tables: q_{T,nu} of eq. (6) is Lipschitz in nu (it integrates
  // y_nu, continuous in (xi, nu) by H1, eq. 2-3 and Remark II3; Gronwall as in Prop. II19), so
  // for u_k <= nu <= u_k+1 the map is interpolated linearly between the two neighbouring
  // tables, q_nu(x_i) ~ q_k(x_i) + a (q_k+1(x_i) - q_k(x_i)), a = (nu - u_k) / mu (error
  // O(mu^2) where q is smooth in nu, O(mu) in general), and eq. (15) is applied to that map:
  // the inverse for the input level nu itself, with no switching instant. nu is the input's
  // mean over the window [t - T, t], the constant input closest to u in L2 over the whole
  // window that eq. (6) integrates (Prop. II18 approximates u by a constant in L1; for a ramp
  // both give the mean). The filter bank z and its delay line do not depend on the level
  // (the algorithm fixes one pair (A, b) for every k, section III step 2), so nothing is reset
  // when the level moves. Measured on example (14) with the paper's parameters
  // (tests/test_finite_time.cpp): window-nearest switching gives peaks of 0.29 at the
  // switches, window-interpolate a maximum error of 0.12 with no peaks; interpolating the two
  // inverses Q_k(eta), Q_k+1(eta) instead gave 0.18 at twice the work per step.
  const std::string rule = choice_option(o, "level-rule",
                                         {"window-interpolate", "window-nearest", "window-floor",
                                          "sample-floor", "sample-nearest", "sample-interpolate"})
                               .value_or("window-interpolate");
  c.window_mean = rule.rfind("window", 0) == 0;
  c.nearest = rule.find("nearest") != std::string::npos;
  c.interpolate = rule.find("interpolate") != std::string::npos;
  c.whiten = choice_option(o, "metric", {"whiten", "scale"}).value_or("whiten") == "whiten";
  if (const auto r = real_option(o, "input-rate")) {
    c.rate = dbl(*r);
    c.rate_given = true;
    if (!(c.rate >= 0)) throw option_error("--input-rate must be >= 0");
  }
  if (const auto k = real_option(o, "backward-steps")) {
    if (!k->is_pos_integer()) throw option_error("--backward-steps: a positive integer");
    c.backward_steps = static_cast<std::size_t>(k->to_long());
  }
  if (const auto e = real_option(o, "error-target")) {
    c.target = dbl(*e);
    if (!(c.target > 0)) throw option_error("--error-target must be positive");
  }
  if (const auto b = real_option(o, "table-memory")) {
    if (!(*b > 0)) throw option_error("--table-memory (KiB) must be positive");
    c.budget_bytes = static_cast<std::size_t>(std::ceil(dbl(*b) * 1024));
  }
}

Choices choose(const Analysis& a, const DesignOptions& o) {
  const Model& m = a.model;
  Choices c;
  c.outputs = m.p();
  choose_window(o, c);
  choose_filters(o, c);
  choose_grid(o, m, c);
  choose_levels(o, m, c);
  choose_kernel(o, c);
  // The correction reads the window's inputs and interpolates like q: only with the
  // window-interpolate rule.
  c.slope = m.m() > 0 && c.levels > 1 && c.window_mean && c.interpolate &&
            choice_option(o, "input-slope", {"correct", "ignore"}).value_or("correct") == "correct";
  return c;
}

// The ramps the sampled bound covers: --input-rate, else (with the slope correction) ramps that
// cross the input's range in ten windows.
double ramp_rate(const Choices& c) {
  if (c.rate_given || !c.slope) return c.rate;
  return (c.input_hi - c.level_lo) / (10 * c.T);
}

// ---- the observation maps q_k -------------------------------------------------------------

class Tabulator {
 public:
  Tabulator(const Model& m, const Choices& c)
      : m_(m), c_(c), field_(m.field(), names(m)), output_(m.h, names(m)) {}

  // q_nu at the given points (one array per state): N x filters, by RK4 backward over [0, T]
  // with the quadrature of e^{lambda_j s} h_(j mod p) carried along (Simpson on the RK4 stages).
  // With rate != 0 the input is the ramp u(t - s) = nu + rate (T/2 - s) over the window (mean
  // nu), for the sampled bound of time-varying inputs; the tables use rate = 0.
  Eigen::MatrixXd map(std::vector<Array> X, double nu, double rate = 0) const {
    const Eigen::Index N = X[0].size();
    const std::size_t n = X.size(), pz = c_.lambda.size();
    const double hs = c_.T / static_cast<double>(c_.backward_steps);
    double s = 0;  // backward time of the stage
    auto rhs = [&](const std::vector<Array>& x, std::vector<Array>& y) {
      std::vector<Array> in = x;
      if (m_.m() > 0) in.push_back(Array::Constant(N, nu + rate * (c_.T / 2 - s)));
      const auto f = field_(in);
      y = output_(x);
      std::vector<Array> dx(n);
      for (std::size_t i = 0; i < n; ++i) dx[i] = -f[i];
      return dx;
    };
    auto add = [&](const std::vector<Array>& x, double a, const std::vector<Array>& k) {
      std::vector<Array> r(n);
      for (std::size_t i = 0; i < n; ++i) r[i] = x[i] + a * k[i];
      return r;
    };
    Eigen::MatrixXd Q = Eigen::MatrixXd::Zero(N, static_cast<Eigen::Index>(pz));
    std::vector<Array> y1, y2, y3, y4;
    for (std::size_t k = 0; k < c_.backward_steps; ++k) {
      const double s0 = static_cast<double>(k) * hs;
      s = s0;
      const auto k1 = rhs(X, y1);
      s = s0 + hs / 2;
      const auto k2 = rhs(add(X, hs / 2, k1), y2);
      const auto k3 = rhs(add(X, hs / 2, k2), y3);
      s = s0 + hs;
      const auto k4 = rhs(add(X, hs, k3), y4);
      s = s0;
      for (std::size_t j = 0; j < pz; ++j) {
        const double l = c_.lambda[j];
        const std::size_t o = j % c_.outputs;
        Q.col(static_cast<Eigen::Index>(j)).array() +=
            hs / 6 *
            (std::exp(l * s) * y1[o] + 2 * std::exp(l * (s + hs / 2)) * (y2[o] + y3[o]) +
             std::exp(l * (s + hs)) * y4[o]);
      }
      for (std::size_t i = 0; i < n; ++i) X[i] += hs / 6 * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i]);
    }
    return Q;
  }

  std::vector<Array> grid() const {
    const std::size_t n = c_.count.size();
    std::size_t N = 1;
    for (auto k : c_.count) N *= k;
    std::vector<Array> X(n, Array(static_cast<Eigen::Index>(N)));
    std::vector<std::size_t> idx(n, 0);
    for (std::size_t i = 0; i < N; ++i) {
      for (std::size_t s = 0; s < n; ++s)
        X[s](static_cast<Eigen::Index>(i)) = c_.lo[s] + c_.step[s] * static_cast<double>(idx[s]);
      for (std::size_t s = n; s-- > 0;) {  // last state fastest
        if (++idx[s] < c_.count[s]) break;
        idx[s] = 0;
      }
    }
    return X;
  }

 private:
  static std::vector<std::string> names(const Model& m) {
    std::vector<std::string> v;
    for (const auto& s : m.states) v.push_back(s.get_name());
    for (const auto& s : m.inputs) v.push_back(s.get_name());
    return v;
  }
  const Model& m_;
  const Choices& c_;
  ArrayFunction field_, output_;
};

// Q(eta) over the table (N x pz) and the grid (N x n): the spec's kernel average.
Eigen::VectorXd kernel_inverse(const Eigen::MatrixXd& table, const Eigen::MatrixXd& grid,
                               const Eigen::RowVectorXd& eta, double eps, int power) {
  const Eigen::ArrayXd d = (table.rowwise() - eta).rowwise().norm().array();
  Eigen::ArrayXd w = (eps + d).inverse();
  const Eigen::ArrayXd w1 = w;
  for (int k = 1; k < power; ++k) w *= w1;
  return (grid.transpose() * w.matrix()) / w.sum();
}

// The Halton point i, counted from 1 (0 is the box's corner).
double halton(std::size_t i, unsigned base) {
  return radical_inverse(i + 1, base);
}

struct Tables {
  std::vector<Eigen::MatrixXd> q;   // per level: N x pz
  std::vector<Eigen::MatrixXd> dq;  // per level, with the slope correction: dq/du' (N x pz)
  Eigen::MatrixXd grid;             // N x n
  double eps = 0;
  double scale = 1;        // median sensitivity after whitening
  Eigen::MatrixXd metric;  // q is stored as metric * q (whitening / scale)
  double synthesis_ms = 0;
  // Sampled accuracy of the inverse.
  double grid_error = 0;          // max |Q_k(q_k(x_i)) - x_i| over a subsample of grid points
  double level_error = 0;         // off-grid test states, u frozen at the levels
  double between_error = 0;       // off-grid test states, u frozen between levels
  double ramp_error = 0;          // off-grid test states, u ramping at +-rate over the window
  double min_separation = 0;      // min over levels and neighbours |q(x_i) - q(x_j)| / |x_i - x_j|
  std::vector<double> sep_where;  // where it is attained
  std::size_t tested = 0;
  double relative_error = 0;  // max over the tests and states of |x_s - xh_s| / box width_s
  // q at the test states per (input mean, ramp rate), in the metric: the kernel search reuses it.
  mutable std::map<std::pair<double, double>, Eigen::MatrixXd> test_maps;
  double bound() const { return std::max({level_error, between_error, ramp_error}); }
};

// Backward simulation from a grid point can leave the finite numbers (Van der Pol's limit
// cycle repels in backward time): say where, instead of tabulating NaN.
void require_finite(const Eigen::MatrixXd& q, const Eigen::MatrixXd& grid, double u,
                    const Choices& c) {
  for (Eigen::Index i = 0; i < q.rows(); ++i) {
    if (q.row(i).allFinite()) continue;
    std::vector<double> x;
    for (Eigen::Index s = 0; s < grid.cols(); ++s) x.push_back(grid(i, s));
    throw UserError(
        SourceLoc{},
        fmt::format("method 'finite-time': the backward simulation over the window T = {:g} from "
                    "the grid point x = ({}) at u = {:g} leaves the finite numbers: the model "
                    "escapes in backward time from the domain box (shrink the box or the window "
                    "with --window)",
                    c.dt * static_cast<double>(c.D), fmt::join(x, ", "), u));
  }
}

// With --metric whiten, q is whitened by its covariance over the grid (W = D^-1/2 V^T,
// eigenvalues floored at 1e-6 of the largest), so that directions in which q varies little (the
// phase, seen only by the fast filters) count as much as the others; returns W (I otherwise).
Eigen::MatrixXd whiten(const Choices& c, Tables& t) {
  const std::size_t pz = c.lambda.size();
  Eigen::MatrixXd W =
      Eigen::MatrixXd::Identity(static_cast<Eigen::Index>(pz), static_cast<Eigen::Index>(pz));
  if (!c.whiten) return W;
  Eigen::VectorXd mean = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(pz));
  Eigen::MatrixXd C =
      Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(pz), static_cast<Eigen::Index>(pz));
  double count = 0;
  for (const auto& q : t.q) {
    mean += q.colwise().sum().transpose();
    count += static_cast<double>(q.rows());
  }
  mean /= count;
  for (const auto& q : t.q) {
    const Eigen::MatrixXd d = q.rowwise() - mean.transpose();
    C += d.transpose() * d;
  }
  C /= count;
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(C);
  Eigen::VectorXd ev = es.eigenvalues();
  const double top = ev.maxCoeff();
  for (Eigen::Index i = 0; i < ev.size(); ++i) ev(i) = 1 / std::sqrt(std::max(ev(i), 1e-6 * top));
  W = ev.asDiagonal() * es.eigenvectors().transpose();
  for (auto& q : t.q) q = q * W.transpose();
  for (auto& q : t.dq) q = q * W.transpose();
  return W;
}

// Neighbour separation in q-space, |q(x_i) - q(x_j)| / |x_i - x_j| along grid edges (sampled
// uniform injectivity): all ratios, the smallest and where into t.
std::vector<double> neighbour_ratios(const Choices& c, Tables& t) {
  const std::size_t n = c.count.size();
  const Eigen::Index N = t.grid.rows();
  std::vector<double> nn;
  t.min_separation = HUGE_VAL;
  std::vector<std::size_t> stride(n, 1);
  for (std::size_t s = n - 1; s-- > 0;) stride[s] = stride[s + 1] * c.count[s + 1];
  for (std::size_t k = 0; k < c.levels; ++k)
    for (Eigen::Index i = 0; i < N; ++i) {
      for (std::size_t s = 0; s < n; ++s) {
        const std::size_t idx = (static_cast<std::size_t>(i) / stride[s]) % c.count[s];
        if (idx + 1 >= c.count[s]) continue;
        const Eigen::Index j = i + static_cast<Eigen::Index>(stride[s]);
        const double ratio = (t.q[k].row(i) - t.q[k].row(j)).norm() / c.step[s];
        nn.push_back(ratio);
        if (ratio < t.min_separation) {
          t.min_separation = ratio;
          t.sep_where.clear();
          for (std::size_t r = 0; r < n; ++r)
            t.sep_where.push_back(t.grid(i, static_cast<Eigen::Index>(r)));
          t.sep_where.push_back(c.level_lo + c.level_step * static_cast<double>(k));
        }
      }
    }
  return nn;
}

// Off-grid test states: a Halton sequence over the grid's box.
std::vector<Array> halton_states(const Choices& c) {
  static const unsigned primes[] = {2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37};
  const std::size_t n = c.count.size(), S = c.bound_samples;
  std::vector<Array> Y(n, Array(static_cast<Eigen::Index>(S)));
  for (std::size_t i = 0; i < S; ++i)
    for (std::size_t s = 0; s < n; ++s) {
      const double hi = c.lo[s] + c.step[s] * static_cast<double>(c.count[s] - 1);
      Y[s](static_cast<Eigen::Index>(i)) = c.lo[s] + (hi - c.lo[s]) * halton(i, primes[s % 12]);
    }
  return Y;
}

// The table of `tables` (q or dq) the level rule picks for the input value v (the runtime's
// rule, spec.hpp SampledDelay): level k's (nearest / floor), or the two neighbouring levels'
// interpolated linearly in v.
Eigen::MatrixXd level_table(const Choices& c, const std::vector<Eigen::MatrixXd>& tables,
                            double v) {
  if (c.levels < 2) return tables[0];
  const double top = static_cast<double>(c.levels - 1);
  const double r = (v - c.level_lo) / c.level_step;
  if (!c.interpolate) {
    const double k = std::floor(r + (c.nearest ? 0.5 : 0.0));
    return tables[k <= 0 ? 0 : k >= top ? c.levels - 1 : static_cast<std::size_t>(k)];
  }
  const double rc = std::clamp(r, 0.0, top);
  const std::size_t k0 = std::min(static_cast<std::size_t>(std::floor(rc)), c.levels - 2);
  const double a = rc - static_cast<double>(k0);
  return tables[k0] + a * (tables[k0 + 1] - tables[k0]);
}

// The table the observer's inverse compares eta with, for the input's value v and slope
// (du/dt over the window, fitted by the runtime): q at v, plus slope * dq at v when corrected.
Eigen::MatrixXd rule_table(const Choices& c, const Tables& t, double v, double slope) {
  Eigen::MatrixXd q = level_table(c, t.q, v);
  if (!t.dq.empty() && slope != 0) q += slope * level_table(c, t.dq, v);
  return q;
}

// The largest inverse error at the test states Y with u over the window the ramp of mean nu and
// slope rate (frozen at nu when rate = 0), for the table the level rule gives; the largest error
// relative to the box widths goes into t.relative_error.
double inverse_error(const Tabulator& tab, const Choices& c, Tables& t, const std::vector<Array>& Y,
                     double nu, double rate) {
  const Eigen::MatrixXd table = rule_table(c, t, c.window_mean ? nu : nu + rate * c.T / 2, rate);
  const std::size_t n = Y.size(), S = static_cast<std::size_t>(Y[0].size());
  auto cached = t.test_maps.find({nu, rate});
  if (cached == t.test_maps.end())
    cached =
        t.test_maps.emplace(std::make_pair(nu, rate), tab.map(Y, nu, rate) * t.metric.transpose())
            .first;
  const Eigen::MatrixXd& q = cached->second;
  double err = 0;
  for (std::size_t i = 0; i < S; ++i) {
    Eigen::VectorXd xi(static_cast<Eigen::Index>(n));
    for (std::size_t s = 0; s < n; ++s)
      xi(static_cast<Eigen::Index>(s)) = Y[s](static_cast<Eigen::Index>(i));
    const Eigen::VectorXd e =
        kernel_inverse(table, t.grid, q.row(static_cast<Eigen::Index>(i)), c.eps, c.power) - xi;
    err = std::max(err, e.norm());
    for (std::size_t s = 0; s < n; ++s)
      t.relative_error =
          std::max(t.relative_error, std::fabs(e(static_cast<Eigen::Index>(s))) / c.width[s]);
  }
  return err;
}

// Accuracy, sampled: grid points (a subsample), off-grid Halton states at the levels and
// between levels (u frozen over the window).
void sampled_accuracy(const Tabulator& tab, const Choices& c, Tables& t) {
  const std::vector<Array> Y = halton_states(c);
  const Eigen::Index N = t.grid.rows();
  t.grid_error = t.level_error = t.between_error = t.ramp_error = t.relative_error = 0;
  const Eigen::Index gstride = std::max<Eigen::Index>(1, N / 200);
  for (std::size_t k = 0; k < c.levels; ++k) {
    for (Eigen::Index i = 0; i < N; i += gstride)
      t.grid_error =
          std::max(t.grid_error, (kernel_inverse(t.q[k], t.grid, t.q[k].row(i), c.eps, c.power) -
                                  t.grid.row(i).transpose())
                                     .norm());
    const double uk = c.level_lo + c.level_step * static_cast<double>(k);
    std::vector<std::pair<double, double*>> inputs = {{uk, &t.level_error}};
    // The worst inputs the level rule maps to level k: up to half a step either side (nearest),
    // or up to the next level (floor); interpolating, inputs between level k and k + 1.
    if (c.interpolate) {
      if (k + 1 < c.levels)
        for (double a : {0.25, 0.5, 0.75})
          inputs.push_back({uk + a * c.level_step, &t.between_error});
    } else if (c.nearest) {
      if (k + 1 < c.levels) inputs.push_back({uk + 0.499 * c.level_step, &t.between_error});
      if (k > 0) inputs.push_back({uk - 0.499 * c.level_step, &t.between_error});
    } else if (k + 1 < c.levels) {
      inputs.push_back({uk + 0.999 * c.level_step, &t.between_error});
      inputs.push_back({uk + 0.5 * c.level_step, &t.between_error});
    }
    for (auto [nu, err] : inputs) *err = std::max(*err, inverse_error(tab, c, t, Y, nu, 0));
    // Ramps at +-rate whose window stays in the input range, with their mean at the same
    // points (clamped into the means such a ramp can have).
    const double rate = ramp_rate(c), half = rate * c.T / 2,
                 hi = c.level_lo + c.level_step * static_cast<double>(c.levels - 1);
    if (rate > 0 && c.level_lo + half <= hi - half)
      for (auto [nu, err] : inputs)
        for (double r : {rate, -rate})
          t.ramp_error = std::max(
              t.ramp_error,
              inverse_error(tab, c, t, Y, std::clamp(nu, c.level_lo + half, hi - half), r));
  }
  t.tested = c.bound_samples;
}

// The tables q_k over the grid, whitened and scaled (sampled_accuracy then measures them).
Tables tabulate(const Tabulator& tab, const Model& m, const Choices& c) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::vector<Array> X = tab.grid();
  const auto N = X[0].size();
  const std::size_t n = m.n();
  Tables t;
  t.grid.resize(N, static_cast<Eigen::Index>(n));
  for (std::size_t s = 0; s < n; ++s) t.grid.col(static_cast<Eigen::Index>(s)) = X[s].matrix();
  for (std::size_t k = 0; k < c.levels; ++k) {
    const double u = c.level_lo + c.level_step * static_cast<double>(k);
    t.q.push_back(tab.map(X, u));
    require_finite(t.q.back(), t.grid, u, c);
    if (c.slope) {  // central difference over ramps that move the input one level per window
      const double delta = c.level_step / c.T;
      t.dq.push_back((tab.map(X, u, delta) - tab.map(X, u, -delta)) / (2 * delta));
      require_finite(t.dq.back(), t.grid, u, c);
    }
  }
  // The kernel's metric: whitened (or not), then scaled by the median sensitivity.
  const Eigen::MatrixXd W = whiten(c, t);
  std::vector<double> nn = neighbour_ratios(c, t);
  // Scale by the median sensitivity s = median |q(x_i) - q(x_j)| / |x_i - x_j| over grid
  // neighbours: kernel distances, and epsilon, are then in state units, so that the grid step
  // and epsilon compare directly (the paper's 0.0125 and 0.05).
  std::sort(nn.begin(), nn.end());
  t.scale = nn.empty() || !(nn[nn.size() / 2] > 0) ? 1 : nn[nn.size() / 2];
  for (auto& q : t.q) q /= t.scale;
  for (auto& q : t.dq) q /= t.scale;
  t.min_separation /= t.scale;
  t.metric = W / t.scale;
  const auto t1 = std::chrono::steady_clock::now();
  t.synthesis_ms = std::chrono::duration<double, std::milli>(t1 - t0).count();
  return t;
}

// ---- the search over window, levels, grid and kernel -------------------------------------

// The model's rate: the median spectral norm of dF/dx over 64 Halton points of the box (states
// and input), by central differences; 0 when it is not finite. Windows are multiples of 1/rate.
double model_rate(const Model& m, const Choices& c) {
  std::vector<std::string> names;
  for (const auto& x : m.states) names.push_back(x.get_name());
  for (const auto& u : m.inputs) names.push_back(u.get_name());
  const ArrayFunction field(m.field(), names);
  const std::size_t n = m.n(), S = 64;
  static const unsigned primes[] = {2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37, 41};
  std::vector<Array> X(n + m.m(), Array(static_cast<Eigen::Index>(S)));
  for (std::size_t i = 0; i < S; ++i) {
    for (std::size_t s = 0; s < n; ++s)
      X[s](static_cast<Eigen::Index>(i)) = c.lo[s] + c.width[s] * halton(i, primes[s % 13]);
    if (m.m() > 0)
      X[n](static_cast<Eigen::Index>(i)) =
          c.level_lo + (c.input_hi - c.level_lo) * halton(i, primes[n % 13]);
  }
  std::vector<Eigen::MatrixXd> J(
      S, Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(n)));
  for (std::size_t s = 0; s < n; ++s) {
    const double h = 1e-6 * std::max(1.0, c.width[s]);
    auto plus = X, minus = X;
    plus[s] += h;
    minus[s] -= h;
    const auto fp = field(plus), fm = field(minus);
    for (std::size_t i = 0; i < S; ++i)
      for (std::size_t r = 0; r < n; ++r)
        J[i](static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(s)) =
            (fp[r](static_cast<Eigen::Index>(i)) - fm[r](static_cast<Eigen::Index>(i))) / (2 * h);
  }
  std::vector<double> norms;
  for (const auto& j : J)
    if (j.allFinite()) norms.push_back(Eigen::JacobiSVD<Eigen::MatrixXd>(j).singularValues()(0));
  if (norms.empty()) return 0;
  std::nth_element(norms.begin(), norms.begin() + static_cast<long>(norms.size() / 2), norms.end());
  return norms[norms.size() / 2];
}

// One setting, measured: its tables and their sampled accuracy (score: t.relative_error).
// nullopt when the backward simulation escapes (the error goes to *escape).
std::optional<Tables> measure(const Model& m, Choices& c, std::optional<UserError>* escape) {
  ++c.candidates;
  try {
    const Tabulator tab(m, c);
    Tables t = tabulate(tab, m, c);
    sampled_accuracy(tab, c, t);
    return t;
  } catch (const UserError& e) {
    if (escape && !*escape) *escape = e;
    return std::nullopt;
  }
}

// The kernel the window and level stages use before the kernel stage: epsilon one grid step,
// power 2n + 4 (local enough that the far field of the grid does not pull the estimate).
void stage_kernel(Choices& c) {
  if (!c.eps_given) c.eps = *std::max_element(c.step.begin(), c.step.end());
  if (!c.power_given) c.power = std::min<int>(16, static_cast<int>(2 * c.lo.size() + 4));
}

std::string percent(double r) {
  return fmt::format("{:.3g} %", 100 * r);
}

// Window T = k / rate, k in 3 .. 11: the smallest sampled error wins, and among windows within
// 20 % of it the shortest (it converges sooner and sees less of the input's variation, which a
// frozen-input bound does not).
void search_window(const Model& m, Choices& c) {
  if (c.window_given) {
    default_poles(c, m.n());
    return;
  }
  const double rate = model_rate(m, c);
  const double w = rate > 0 && std::isfinite(rate) ? rate : 5;
  std::vector<std::pair<double, double>> scores;  // (T, score)
  std::optional<UserError> escape;
  for (double k : {3.0, 4.0, 5.0, 6.5, 8.5, 11.0}) {
    set_window(c, k / w);
    default_poles(c, m.n());
    if (!fill_grid(c)) break;
    stage_kernel(c);
    if (const auto t = measure(m, c, &escape)) scores.push_back({c.T, t->relative_error});
  }
  if (scores.empty() && escape) throw *escape;
  double best = HUGE_VAL, T = scores.empty() ? 3 / w : scores.front().first;
  for (const auto& sc : scores) best = std::min(best, sc.second);
  for (const auto& sc : scores)
    if (sc.second <= 1.2 * best) {
      T = sc.first;
      break;
    }
  set_window(c, T);
  default_poles(c, m.n());
  std::vector<std::string> tried;
  for (const auto& sc : scores)
    tried.push_back(fmt::format("{:g}: {}", sc.first, percent(sc.second)));
  c.notes.push_back(fmt::format(
      "window T = {:g} searched (model rate {:.4g} = median |dF/dx|; T = k / rate; sampled error "
      "per window {}; the shortest within 20 % of the best)",
      c.T, rate, fmt::join(tried, ", ")));
  c.notes.push_back(fmt::format("{} filter poles geometric from -0.2/T to -20/T", c.lambda.size()));
}

// The number of input levels (5, 10 or 20 steps over the input's range), the grid filling the
// budget that remains: the smallest sampled error wins.
void search_levels(const Model& m, Choices& c) {
  if (m.m() == 0 || c.levels_given || !(c.input_hi > c.level_lo)) return;
  double best = HUGE_VAL;
  std::size_t chosen = 11;
  std::vector<std::string> tried;
  for (std::size_t L : {11, 6, 21}) {
    c.levels = L;
    c.level_step = (c.input_hi - c.level_lo) / static_cast<double>(L - 1);
    if (!fill_grid(c)) continue;
    stage_kernel(c);
    const auto t = measure(m, c, nullptr);
    if (!t) continue;
    tried.push_back(fmt::format("{}: {}", L, percent(t->relative_error)));
    if (t->relative_error < best) best = t->relative_error, chosen = L;
  }
  c.levels = chosen;
  c.level_step = (c.input_hi - c.level_lo) / static_cast<double>(chosen - 1);
  c.notes.push_back(fmt::format("{} input levels searched (sampled error per level count {})",
                                chosen, fmt::join(tried, ", ")));
}

// Epsilon (1/2, 1, 2 grid steps) and weight power (n + 2, 2n + 4, 4n + 4) on the chosen tables;
// returns the final tables with their accuracy over the full test set.
Tables search_kernel(const Model& m, Choices& c) {
  if (!fill_grid(c))
    throw option_error(fmt::format(
        "method 'finite-time': no grid of 3 or more points per state fits the table-memory "
        "budget of {} ({} filters x {} input levels); raise --table-memory",
        c.budget_bytes, c.lambda.size(), c.levels));
  const Tabulator tab(m, c);
  Tables t = tabulate(tab, m, c);
  ++c.candidates;
  const double h = *std::max_element(c.step.begin(), c.step.end());
  const int n = static_cast<int>(m.n());
  std::vector<double> eps =
      c.eps_given ? std::vector<double>{c.eps} : std::vector<double>{h, h / 2, 2 * h};
  std::vector<int> powers = c.power_given
                                ? std::vector<int>{c.power}
                                : std::vector<int>{2 * n + 4, n + 2, std::min(16, 4 * n + 4)};
  double best = HUGE_VAL, best_eps = eps[0];
  int best_power = powers[0];
  for (double e : eps)
    for (int p : powers) {
      c.eps = e;
      c.power = p;
      sampled_accuracy(tab, c, t);
      if (t.relative_error < best) best = t.relative_error, best_eps = e, best_power = p;
    }
  c.eps = best_eps;
  c.power = best_power;
  if (eps.size() > 1 || powers.size() > 1)
    c.notes.push_back(
        fmt::format("kernel searched: epsilon {:.4g} ({:g} grid steps), weight "
                    "power {} (of epsilon 1/2, 1, 2 steps x power n+2, 2n+4, 4n+4)",
                    c.eps, c.eps / h, c.power));
  c.bound_samples = 300;
  t.test_maps.clear();
  sampled_accuracy(tab, c, t);
  return t;
}

// The whole design: what the options fix stays; window, levels, grid and kernel are searched
// (at most 6 + 3 tabulations and 9 kernels, 150 test states each) for the smallest sampled error
// within the memory budget; the final accuracy uses 300 test states.
Tables design_tables(const Model& m, Choices& c) {
  c.bound_samples = 150;
  if (!c.eps_given && c.grid_given) c.eps = *std::max_element(c.step.begin(), c.step.end());
  search_window(m, c);
  search_levels(m, c);
  return search_kernel(m, c);
}

// ---- verdict and spec -------------------------------------------------------------------

// Whether the model qualifies (at most one input, bound parameters, a box).
Verdict requirements(const Analysis& a) {
  const Model& m = a.model;
  Verdict v;
  if (m.m() > 1)
    v.reasons.push_back(
        fmt::format("finite-time: at most one input selects the inverse table (m = {})", m.m()));
  if (!m.free_params().empty())
    v.reasons.push_back(
        "finite-time: q is tabulated numerically; bind the free parameters with --param");
  std::vector<std::string> missing;
  for (const auto* syms : {&m.states, &m.inputs})
    for (const auto& s : *syms)
      if (!m.domain.count(s.get_name())) missing.push_back(s.get_name());
  if (!missing.empty())
    v.reasons.push_back(fmt::format(
        "finite-time: the domain line must bound {} (the compact state region and input range "
        "the tables cover)",
        fmt::join(missing, ", ")));
  v.applies = v.reasons.empty();
  if (v.applies)
    v.reasons.push_back(
        "finite-time: needs no derivatives (h may be non-smooth); the domain box gives the "
        "compact region G and input range U; injectivity of q and the accuracy are checked "
        "numerically (sampled) when the tables are built");
  return v;
}

// The sampled accuracy against the target and the memory against the budget.
struct Outcome {
  bool target_met = false, within_budget = false;
  std::size_t entries = 0;
};

Outcome outcome(const Choices& c) {
  Outcome o;
  o.entries = table_entries(c);
  o.within_budget = o.entries * 4 <= c.budget_bytes;
  return o;
}

std::string memory_text(std::size_t bytes);

// The guarantee line: partial (a sampled bound, not a proof) when the target is met within the
// budget, none otherwise (an observer whose own bound says it misses its target).
void set_guarantee(Verdict& v, const Choices& c, const Tables& t) {
  Outcome o = outcome(c);
  o.target_met = t.relative_error <= c.target;
  const std::string measured = fmt::format(
      "sampled error bound {:.4g} (max |x_s - xh_s| = {} of the state's box width over {} test "
      "states, u frozen{}), target {}, tables {} as float (budget {})",
      t.bound(), percent(t.relative_error), t.tested,
      ramp_rate(c) > 0 ? fmt::format(" or ramping at +-{:.3g}", ramp_rate(c)) : std::string(),
      percent(c.target), memory_text(o.entries * 4), memory_text(c.budget_bytes));
  if (o.target_met && o.within_budget) {
    v.guarantee = Guarantee::partial;
    v.guarantee_text = "finite-time: target met (sampled, not a proof): " + measured;
  } else {
    v.guarantee = Guarantee::none;
    v.guarantee_text =
        fmt::format("finite-time: {}: {}",
                    !o.within_budget ? "the tables exceed the memory budget"
                                     : "no setting searched meets the error target (raise "
                                       "--table-memory or --error-target)",
                    measured);
  }
}

// The verdict carries the guarantee of the tables once its plan has built them (`built`); before,
// it stays cheap (the main job's report asks every design's verdict; the search takes seconds).
Verdict verdict_of(const Analysis& a, const Verdict* built) {
  Verdict v = requirements(a);
  if (!v.applies) return v;
  if (built) {
    v.guarantee = built->guarantee;
    v.guarantee_text = built->guarantee_text;
  } else {
    v.guarantee = Guarantee::none;
    v.guarantee_text =
        "finite-time: its sampled error bound comes with its tables (a search of seconds), "
        "built only by --method finite-time; not built here";
  }
  return v;
}

std::string list(const std::vector<double>& v) {
  std::vector<std::string> s;
  for (double d : v) s.push_back(fmt::format("{:g}", d));
  return fmt::format("{}", fmt::join(s, ", "));
}

// The runtime's sampled-delay description (without its metric table).
SampledDelay sampled_delay(const Choices& c) {
  SampledDelay d;
  d.sample_period = c.dt;
  d.delay_steps = c.D;
  d.filters = c.lambda.size();
  d.decay_table = "filter_decay";
  d.gain_table = "filter_gain";
  d.delay_table = "delay_decay";
  d.map_table = "observation_map";
  if (c.slope) d.slope_table = "observation_slope";
  d.grid_lo = c.lo;
  d.grid_step = c.step;
  d.grid_count = c.count;
  d.input_index = 0;
  d.outputs = c.outputs;
  d.level_lo = c.level_lo;
  d.level_step = c.level_step;
  d.levels = c.levels;
  d.level_nearest = c.nearest;
  d.level_window_mean = c.window_mean;
  d.level_interpolate = c.interpolate;
  d.epsilon = c.eps;
  d.weight_power = c.power;
  return d;
}

// The constant tables: the filter bank over one sample, the delay's decay, the kernel metric
// and the observation maps q_k (in the order the spec lists them).
std::vector<ConstTable> const_tables(const Choices& c, const Tables& t, double T) {
  const std::size_t pz = c.lambda.size(), N = static_cast<std::size_t>(t.grid.rows());
  ConstTable decay{"filter_decay", {pz}, {}, "e^{lambda_i dt}: the filter bank over one sample"};
  ConstTable gain{"filter_gain", {pz}, {}, "(e^{lambda_i dt} - 1) / lambda_i: y held, b = 1"};
  ConstTable delay{"delay_decay", {pz}, {}, "e^{lambda_i T}: eta = z - e^{A T} z(t - T)"};
  for (double l : c.lambda) {
    decay.values.push_back(std::exp(l * c.dt));
    gain.values.push_back(std::expm1(l * c.dt) / l);
    delay.values.push_back(std::exp(l * T));
  }
  // One table per input level, [level k][grid point i][filter j].
  const auto per_level = [&](const char* name, const std::vector<Eigen::MatrixXd>& tables,
                             const char* doc) {
    ConstTable table{name, {c.levels, N, pz}, {}, doc};
    table.values.reserve(c.levels * N * pz);
    for (std::size_t k = 0; k < c.levels; ++k)
      for (std::size_t i = 0; i < N; ++i)
        for (std::size_t j = 0; j < pz; ++j)
          table.values.push_back(
              tables[k](static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)));
    return table;
  };
  const ConstTable map =
      per_level("observation_map", t.q,
                "q_k(x_i): [input level k][grid point i][filter j], by backward simulation");
  ConstTable metric{"kernel_metric",
                    {pz, pz},
                    {},
                    "M: the inverse compares M eta with the table (whitening / scale)"};
  for (std::size_t i = 0; i < pz; ++i)
    for (std::size_t j = 0; j < pz; ++j)
      metric.values.push_back(t.metric(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)));
  if (!c.slope) return {decay, gain, delay, metric, map};
  return {decay,
          gain,
          delay,
          metric,
          map,
          per_level("observation_slope", t.dq,
                    "dq_k/du'(x_i): the maps' sensitivity to the input's slope over the window")};
}

// Title, description, class documentation and constants; bound is the sampled error bound.
void describe_finite_time(ObserverSpec& s, const Choices& c, const Tables& t, double T,
                          double bound, const Verdict& g) {
  const std::size_t N = static_cast<std::size_t>(t.grid.rows());
  const std::string covered = ramp_rate(c) > 0
                                  ? fmt::format("frozen or ramping at up to {:.3g}", ramp_rate(c))
                                  : std::string("frozen");
  s.title = "Finite-time epsilon-T observer (Kreisselmeier-Engel filter bank, tabulated inverse)";
  s.description = {
      "Observer: finite-time epsilon-T observer (Garcia & Hernandez, seed 004, eq. 10, 15)",
      fmt::format("Window T = {:g} = {} samples of {:g}; filter poles {}", T, c.D, c.dt,
                  list(c.lambda)),
      fmt::format("Inverse: kernel average over a {} grid ({} points), {} input level{}, "
                  "epsilon {:.6g}, weight power {}",
                  fmt::join(c.count, " x "), N, c.levels, c.levels == 1 ? "" : "s", c.eps, c.power),
      fmt::format("Sampled accuracy: |x - xh| <= {:.4g} for u {} over the window (not a proof)",
                  bound, covered),
      g.guarantee == Guarantee::partial
          ? fmt::format("Error target {} of the box width: met (sampled)", percent(c.target))
          : fmt::format("WARNING: error target {} of the box width NOT met: sampled error {}",
                        percent(c.target), percent(t.relative_error))};
  s.class_doc = {"  z <- e^{A dt} z + A^-1 (e^{A dt} - I) b y,  eta = z - e^{A T} z(t - T),",
                 "  xh = sum_i x_i w_i / sum_i w_i,  w_i = (epsilon + |eta - q_k(x_i)|)^-power,"};
  if (c.interpolate && c.levels > 1) {
    s.class_doc.push_back(
        "with q_k interpolated linearly between the input levels level() and level() + 1");
    s.class_doc.push_back(
        fmt::format("around the input's {}. step() accepts only the design's sample",
                    c.window_mean ? "mean over the window" : "value now"));
  } else {
    s.class_doc.push_back(
        "with k the level of the input at this step. step() accepts only the design's sample");
  }
  s.class_doc.push_back(
      "period; until T has passed since reset() the estimate stays the reset value.");
  if (c.outputs > 1)
    s.class_doc.push_back(fmt::format(
        "{} outputs: filter j is fed y_(j mod {}) (the filters are dealt round the outputs).",
        c.outputs, c.outputs));
  s.class_doc.push_back(
      fmt::format("Sampled accuracy (u {} over the window): |x - xh| <= {:.4g}.", covered, bound));
  std::vector<GiNaC::numeric> poles;
  for (double l : c.lambda) poles.push_back(GiNaC::numeric(l));
  s.constants.push_back({"filter_poles", poles, "eigenvalues of the diagonal A"});
}

std::string memory_text(std::size_t bytes) {
  return bytes >= 1 << 20 ? fmt::format("{:.2f} MiB", static_cast<double>(bytes) / (1 << 20))
                          : fmt::format("{:.1f} KiB", static_cast<double>(bytes) / 1024);
}

// The report rows (with the notes on defaults) and the summary.
void report_finite_time(ObserverSpec& s, const Model& m, const Choices& c, const Tables& t,
                        double T, double bound, std::size_t entries, const Verdict& g) {
  const std::size_t pz = c.lambda.size(), N = static_cast<std::size_t>(t.grid.rows());
  std::vector<std::string> per_state;
  for (std::size_t i = 0; i < m.n(); ++i)
    per_state.push_back(
        fmt::format("{:.4g} for {}", c.target * c.width[i], m.states[i].get_name()));
  s.report = {
      {"guarantee", fmt::format("{}: {}", guarantee_name(g.guarantee), g.guarantee_text)},
      {"error target",
       fmt::format("{} of each state's box width ({}; --error-target): {}", percent(c.target),
                   fmt::join(per_state, ", "),
                   t.relative_error <= c.target
                       ? fmt::format("met, sampled error {}", percent(t.relative_error))
                       : fmt::format("NOT met, sampled error {}", percent(t.relative_error)))},
      {"table memory budget",
       fmt::format("{} at 4 bytes an entry (--table-memory, KiB): {} used as float{}",
                   memory_text(c.budget_bytes), memory_text(entries * 4),
                   entries * 4 <= c.budget_bytes ? "" : ", OVER the budget")},
      {"search", fmt::format("{} settings tabulated (deterministic: fixed candidates, Halton test "
                             "states); options given are kept",
                             c.candidates)},
      {"window T",
       fmt::format("{:g} ({} samples of {:g}; --window, --sample-period)", T, c.D, c.dt)},
      {"filter poles", list(c.lambda)},
      {"kernel metric",
       fmt::format("{}, then divided by s = {:.4g} = median |q(x_i) - q(x_j)| / |x_i - x_j| "
                   "over grid neighbours: kernel distances and epsilon in state units",
                   c.whiten ? "q whitened by its covariance over the grid" : "q as is", t.scale)},
      {"state grid",
       fmt::format("{} points ({}), step {}", N, fmt::join(c.count, " x "), list(c.step))},
      {"input levels",
       m.m()
           ? fmt::format("{} levels from {:g} step {:g}; {} {}", c.levels, c.level_lo, c.level_step,
                         c.interpolate ? "q interpolated linearly between the two levels around"
                         : c.nearest   ? "Q_k for the level nearest"
                                       : "Q_k for the level at or below",
                         c.window_mean ? "the input's mean over the window" : "the input now") +
                 (c.slope ? "; plus its slope over the window (least squares) times dq/du', "
                            "tabulated per level (--input-slope)"
                          : "")
           : std::string("1 (no input)")},
      {"kernel", fmt::format("epsilon {:.6g}, weight power {} ({})", c.eps, c.power,
                             c.power == 1 ? "eq. 15" : "eq. 13 form")},
      {"table memory (flash)", fmt::format("{} entries: {} as float, {} as double", entries,
                                           memory_text(entries * 4), memory_text(entries * 8))},
      {"delay line memory (RAM)",
       fmt::format("{} x {} entries: {} as float, {} as double", c.D + 1, pz,
                   memory_text((c.D + 1) * pz * 4), memory_text((c.D + 1) * pz * 8))},
      {"work per step", fmt::format("{} kernel terms of {} filters", N, pz)},
      {"injectivity (sampled)",
       fmt::format("min |q(x_i) - q(x_j)| / |x_i - x_j| over grid neighbours = {:.3g} at x = "
                   "({}), u = {:g}",
                   t.min_separation,
                   list(std::vector<double>(t.sep_where.begin(), t.sep_where.end() - 1)),
                   t.sep_where.back())},
      {"inverse error at grid points (sampled)", fmt::format("{:.3g}", t.grid_error)},
      {"error bound (sampled)",
       fmt::format("{:.4g} = max |Q_k(q_u(x)) - x| over {} Halton states in the box and u "
                   "frozen at the levels ({:.3g}) and between them ({:.3g}){}",
                   bound, t.tested, t.level_error, t.between_error,
                   ramp_rate(c) > 0
                       ? fmt::format(", and u ramping at +-{:.3g} over the window ({:.3g}); "
                                     "faster inputs are not covered",
                                     ramp_rate(c), t.ramp_error)
                       : std::string("; a time-varying u adds to it (--input-rate covers "
                                     "ramps)"))},
  };
  for (const auto& note : c.notes) s.report.push_back({"default", note});
  s.summary = fmt::format(
      "finite-time epsilon-T observer: T = {:g}, {} filters, {} grid points x {} input levels, "
      "sampled error bound {:.4g} ({} of the box; target {} {})",
      T, pz, N, c.levels, bound, percent(t.relative_error), percent(c.target),
      g.guarantee == Guarantee::partial ? "met" : "NOT met");
}

// Builds the tables and the observer; g receives the tables' guarantee.
ObserverSpec build(const Analysis& a, const DesignOptions& o, Verdict& g) {
  const Model& m = a.model;
  const Verdict v = requirements(a);
  if (!v.applies)
    throw UserError(SourceLoc{m.file, 0, 0}, "method 'finite-time' does not apply: " + v.text());
  Choices c = choose(a, o);
  const Tables t = design_tables(m, c);
  set_guarantee(g, c, t);
  const std::size_t pz = c.lambda.size();

  ObserverSpec s;
  s.method = "finite-time";
  s.class_suffix = "FiniteTime";
  s.state_size = m.n();
  s.state_name = "xh";
  s.state_doc = "the estimate (the filter bank and its delay line are kept separately)";
  s.update = UpdateKind::sampled_delay;
  s.estimate = EstimateKind::identity;
  s.functions = model_functions(m);

  SampledDelay d = sampled_delay(c);
  const double T = c.dt * static_cast<double>(c.D);
  d.metric_table = "kernel_metric";
  s.tables = const_tables(c, t, T);
  s.sampled_delay = d;

  const std::size_t entries = table_entries(c);
  (void)pz;
  const double bound = t.bound();
  describe_finite_time(s, c, t, T, bound, g);
  report_finite_time(s, m, c, t, T, bound, entries, g);
  return s;
}

}  // namespace

// Its verdict reports the guarantee of the tables its own build made (none before).
class FiniteTimePlan final : public Plan {
 public:
  FiniteTimePlan(const Analysis& a, const DesignOptions& o) : a_(a), o_(o) {}
  Verdict verdict() override { return verdict_of(a_, built_ ? &*built_ : nullptr); }
  ObserverSpec build() override {
    Verdict g;
    ObserverSpec s = obsynth::build(a_, o_, g);
    built_ = std::move(g);
    return s;
  }

 private:
  const Analysis& a_;
  DesignOptions o_;
  std::optional<Verdict> built_;
};

Design finite_time_design() {
  Design d;
  d.name = "finite-time";
  d.summary =
      "finite-time epsilon-T observer: filter bank, delay line and tabulated inverse per input "
      "level (seed 004; no derivatives, non-smooth h)";
  d.options = {
      {"window", "finite-time: the window T", "searched: k / (median |dF/dx|), k = 3 .. 11"},
      {"sample-period", "finite-time: the fixed sample period dt (T must be a multiple)",
       "T/100 (simulate: --dt)"},
      {"filter-poles", "finite-time: eigenvalues of the diagonal filter bank A, negative",
       "2n+1 geometric from -0.2/T to -20/T"},
      {"grid-step", "finite-time: state grid step (one, or one per state) over the domain box",
       "as many points as --table-memory holds"},
      {"input-step", "finite-time: spacing of the input levels over the input's domain",
       "searched: 1/5, 1/10 or 1/20 of the range"},
      {"kernel-epsilon", "finite-time: epsilon of the inverse's weights (eq. 13/15)",
       "searched: 1/2, 1 or 2 grid steps"},
      {"weight-power", "finite-time: power of the weights, 1 (eq. 15) or n+2 (eq. 13)",
       "searched: n+2, 2n+4, 4n+4"},
      {"metric",
       "finite-time: kernel distance: whiten (q whitened by its covariance over the grid) or "
       "scale",
       "whiten"},
      {"level-rule",
       "finite-time: input level of the inverse: window-interpolate (q interpolated linearly "
       "between the two levels around the input's mean over the window), window-nearest (the "
       "level nearest that mean), window-floor, sample-floor (the paper's u_k <= u(t) < "
       "u_k+1), sample-nearest, sample-interpolate",
       "window-interpolate"},
      {"input-rate", "finite-time: |du/dt| of the input ramps the sampled error bound also covers",
       "with --input-slope correct: the input's range over 10 windows; else 0"},
      {"input-slope",
       "finite-time: correct (a second table per level, dq/du', applied with the input's slope "
       "fitted over the window: first order in the slope) or ignore (u taken as frozen at its "
       "mean)",
       "correct (models with an input and more than one level)"},
      {"backward-steps", "finite-time: RK4 steps of the backward simulation over T", "200"},
      {"error-target",
       "finite-time: sampled error target, a fraction of each state's box width (the search "
       "aims under it; the verdict says when no setting meets it)",
       "0.05"},
      {"table-memory",
       "finite-time: budget of the inverse tables in KiB, at 4 bytes an entry (float)", "256"}};
  d.plan = [](const Analysis& a, const DesignOptions& o) -> std::unique_ptr<Plan> {
    return std::make_unique<FiniteTimePlan>(a, o);
  };
  d.in_all = false;  // tables of 10^4..10^6 entries: by name only, not by auto or all
  d.observes_output_offset = false;  // feeds y itself to its filter bank
  return d;
}

}  // namespace obsynth
