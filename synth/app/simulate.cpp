#include "app/simulate.hpp"

#include <fmt/format.h>

#include <cmath>
#include <memory>

#include "app/svg_plot.hpp"
#include "emit/dag.hpp"
#include "front/parse.hpp"
#include "obsynth/differentiator.hpp"

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

// Newton on T(x) = z with [tau] as inverse Jacobian, as the runtime does.
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

SimulationResult simulate(const Analysis& a, const SimulationOptions& opt) {
  const Model& m = a.model;
  const CanonicalForm& cf = a.canonical;
  const std::size_t n = m.n();
  if (!m.free_params().empty())
    throw UserError(SourceLoc{m.file, 0, 0}, "simulate: free parameter '" +
                                                 m.free_params()[0].get_name() + "' needs a value");
  if (opt.x0.size() != n)
    throw UserError(SourceLoc{}, fmt::format("--x0 needs {} values, got {}", n, opt.x0.size()));
  if (opt.xhat0.size() != n)
    throw UserError(SourceLoc{},
                    fmt::format("--xhat0 needs {} values, got {}", n, opt.xhat0.size()));
  if (!(opt.dt > 0) || !(opt.t_end > 0))
    throw UserError(SourceLoc{}, "--dt and --t-end must be positive");
  const double steps_d = std::ceil(opt.t_end / opt.dt - 1e-9);
  if (steps_d > 5e7)
    throw UserError(SourceLoc{}, "simulate: more than 5e7 steps; raise --dt or lower --t-end");
  const std::size_t steps = static_cast<std::size_t>(steps_d);

  GiNaC::symbol tsym("t");
  ExVec u_of_t = parse_expression_list(opt.u_text, "--u", {tsym});
  if (m.m() == 0 && opt.u_text == "0") u_of_t.clear();
  if (u_of_t.size() != m.m())
    throw UserError(SourceLoc{},
                    fmt::format("--u needs {} expression{} in t (one per input), got {}", m.m(),
                                m.m() == 1 ? "" : "s", u_of_t.size()));
  const NumericFunction u_fn(u_of_t, {"t"});

  const std::vector<std::string> xn = names_of(m.states), un = names_of(m.inputs);
  const NumericFunction plant(m.field(), concat_names(xn, un));
  const NumericFunction output(m.h, xn);
  SimulationResult res;
  res.names = xn;
  auto record = [&](double t, const Vec& x, const Vec& xh) {
    res.t.push_back(t);
    res.x.push_back(x);
    res.xh.push_back(xh);
  };

  Vec x = opt.x0;
  if (opt.method == "canonical") {
    const CanonicalDesign d = design_canonical(a, opt.canonical);
    const std::string yname = cf.y.get_name();
    // Observer ODE: the same expressions as the generated derivative().
    NumericFunction obs_rhs, to_state, from_state, T_fn, frame_fn;
    if (d.realisation == Realisation::z) {
      ExVec c;
      for (std::size_t i = 0; i < n; ++i) c.push_back(a.canonical.l[i] + d.K[i] * (cf.y - d.y0));
      GiNaC::exmap cs;
      for (std::size_t i = 0; i < n; ++i) cs[d.c[i]] = c[i];
      ExVec rhs;
      for (const auto& e : d.z_rhs) rhs.push_back(e.subs(cs));
      std::vector<std::string> in = names_of(d.zh);
      in = concat_names(concat_names(in, un), {yname});
      obs_rhs = NumericFunction(rhs, in);
      T_fn = NumericFunction(cf.T, xn);
      if (d.newton_inverse) {
        frame_fn = NumericFunction(frame_column_major(cf), xn);
      } else {
        from_state = NumericFunction(cf.T_inverse, names_of(cf.z));
      }
    } else {
      obs_rhs = NumericFunction(d.x_rhs, concat_names(concat_names(xn, un), {yname}));
    }
    auto estimate = [&](const Vec& s, const Vec& seed) -> Vec {
      if (d.realisation == Realisation::x) return s;
      if (d.newton_inverse)
        return newton(T_fn, frame_fn, s, seed, opt.newton_iterations, opt.newton_tolerance);
      return from_state(s);
    };
    Vec s = d.realisation == Realisation::z ? T_fn(opt.xhat0) : opt.xhat0;
    Vec xh = opt.xhat0;
    record(0, x, xh);
    for (std::size_t k = 0; k < steps; ++k) {
      const double t = static_cast<double>(k) * opt.dt;
      if (opt.sampling == Sampling::continuous) {
        // One ODE: [x; s]' = [f + g(x, u(t)); observer(s, u(t), h(x))].
        Vec xs = concat(x, s);
        rk4(
            [&](double tt, const Vec& v) {
              const Vec xv(v.begin(), v.begin() + static_cast<long>(n));
              const Vec sv(v.begin() + static_cast<long>(n), v.end());
              const Vec u = u_fn({tt});
              const Vec y = output(xv);
              return concat(plant(concat(xv, u)), obs_rhs(concat(concat(sv, u), y)));
            },
            t, opt.dt, xs);
        x.assign(xs.begin(), xs.begin() + static_cast<long>(n));
        s.assign(xs.begin() + static_cast<long>(n), xs.end());
      } else {
        // Firmware semantics: u_k, y_k held over the step for the observer.
        const Vec uk = u_fn({t});
        const Vec yk = output(x);
        rk4([&](double, const Vec& sv) { return obs_rhs(concat(concat(sv, uk), yk)); }, t, opt.dt,
            s);
        rk4([&](double tt, const Vec& xv) { return plant(concat(xv, u_fn({tt}))); }, t, opt.dt, x);
      }
      xh = estimate(s, xh);
      record(static_cast<double>(k + 1) * opt.dt, x, xh);
    }
  } else if (opt.method == "perfect") {
    const PerfectDesign d = design_perfect(a);
    std::vector<std::string> in;
    for (const auto& s : d.y_jet) in.push_back(s.get_name());
    for (const auto& jet : d.u_jet)
      for (const auto& s : jet) in.push_back(s.get_name());
    const NumericFunction recon(d.newton_inverse ? d.z : d.x, in);
    NumericFunction T_fn, frame_fn;
    if (d.newton_inverse) {
      T_fn = NumericFunction(cf.T, xn);
      frame_fn = NumericFunction(frame_column_major(cf), xn);
    }
    auto ydiff = make_jet(n - 1, opt.epsilon);
    std::vector<std::unique_ptr<Jet>> udiff;
    const std::size_t uk = std::max<std::size_t>(n, 2) - 2;
    for (std::size_t j = 0; j < m.m(); ++j) udiff.push_back(make_jet(uk, opt.epsilon));
    ydiff->reset(output(opt.xhat0)[0]);
    for (auto& dj : udiff) dj->reset(0);
    Vec xh = opt.xhat0;
    record(0, x, xh);
    for (std::size_t k = 0; k < steps; ++k) {
      const double t = static_cast<double>(k) * opt.dt;
      rk4([&](double tt, const Vec& xv) { return plant(concat(xv, u_fn({tt}))); }, t, opt.dt, x);
      const double t1 = static_cast<double>(k + 1) * opt.dt;
      ydiff->update(opt.dt, output(x)[0]);
      const Vec u1 = u_fn({t1});
      for (std::size_t j = 0; j < m.m(); ++j) udiff[j]->update(opt.dt, u1[j]);
      Vec jets = ydiff->jet();
      for (auto& dj : udiff) jets = concat(jets, dj->jet());
      const Vec r = recon(jets);
      xh = d.newton_inverse
               ? newton(T_fn, frame_fn, r, xh, opt.newton_iterations, opt.newton_tolerance)
               : r;
      record(t1, x, xh);
    }
  } else {
    throw UserError(
        SourceLoc{},
        fmt::format("simulate: method '{}' is not implemented (canonical, perfect)", opt.method));
  }

  // CSV with full precision, and the plot.
  res.csv = csv_header(xn);
  for (std::size_t i = 0; i < res.t.size(); ++i) {
    res.csv += fmt::format("{:.10g}", res.t[i]);
    for (double v : res.x[i]) res.csv += fmt::format(",{:.17g}", v);
    for (double v : res.xh[i]) res.csv += fmt::format(",{:.17g}", v);
    res.csv += "\n";
  }
  TrajectoryPlot plot{
      fmt::format("{}: {} observer ({} sampling), u = {}", m.name, opt.method,
                  opt.sampling == Sampling::continuous ? "continuous" : "zero-order hold",
                  opt.u_text),
      xn, res.t, res.x, res.xh};
  res.svg = render_svg(plot);
  double e0 = 0, e1 = 0;
  for (std::size_t k = 0; k < n; ++k) {
    e0 = std::max(e0, std::fabs(res.x.front()[k] - res.xh.front()[k]));
    e1 = std::max(e1, std::fabs(res.x.back()[k] - res.xh.back()[k]));
  }
  res.summary = fmt::format("{} steps of {:g}: max |x - x_hat| {:.3e} at t = 0, {:.3e} at t = {:g}",
                            steps, opt.dt, e0, e1, res.t.back());
  return res;
}

}  // namespace obsynth
