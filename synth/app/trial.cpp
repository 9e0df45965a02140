#include "app/trial.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include <Eigen/Eigenvalues>

#include "app/simulate.hpp"
#include "symbolic/dag.hpp"

namespace obsynth {

namespace {

constexpr double kInitialError = 0.20;    // share of each state's box width
constexpr double kStartShare = 0.45;      // x0 = lo + 0.45 width (off the centre's symmetries)
constexpr double kHorizonSpans = 300;     // horizon, in time constants 1 / rho
constexpr double kStepShare = 0.02;       // RK4 step, in time constants
constexpr double kPlantSlack = 0.5;       // the plant may overshoot the box by half a width
constexpr double kEstimateSlack = 2.0;    // the estimate, by two widths
constexpr double kFinalWindow = 0.10;     // the final error: max over the last 10 % of the run
constexpr double kConverged = 0.02;       // converged: final error below 2 % of the box ...
constexpr double kReduction = 0.10;       // ... and below a tenth of the initial error
constexpr std::size_t kMaxSteps = 40000;  // per run (a time budget for stiff models)

struct Box {
  std::vector<double> lo, width;
};

Box state_box(const Model& m) {
  Box b;
  for (const auto& x : m.states) {
    const Interval i = m.box(x);
    b.lo.push_back(i.lo.to_double());
    b.width.push_back(std::max(i.hi.to_double() - i.lo.to_double(), 1e-300));
  }
  return b;
}

// The parameters as the observer sees them: bound values, free ones at their run-time default.
GiNaC::exmap parameter_values(const Model& m, const ObserverSpec& spec) {
  GiNaC::exmap at;
  for (const auto& p : m.params)
    if (p.value) at[p.symbol] = *p.value;
  for (const auto& p : spec.params) at[p.symbol] = p.default_value;
  return at;
}

double input_centre(const Model& m, std::size_t j) {
  if (m.domain.count(m.inputs[j].get_name())) {
    const Interval b = m.box(m.inputs[j]);
    return (b.lo.to_double() + b.hi.to_double()) / 2;
  }
  return m.nominal.empty() ? 0.0 : m.nominal[j].to_double();
}

// rho: the largest |eigenvalue| of d(f + g)/dx at x0 and at four more box points, inputs at
// their centres; 1 when the field is nilpotent there (a chain of integrators).
double time_scale(const Model& m, const GiNaC::exmap& params, const Box& box) {
  const std::size_t n = m.n();
  std::vector<GiNaC::ex> jac;
  const ExVec field = m.field();
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = 0; j < n; ++j) jac.push_back(field[i].diff(m.states[j]).subs(params));
  std::vector<std::string> names;
  for (const auto& x : m.states) names.push_back(x.get_name());
  for (const auto& u : m.inputs) names.push_back(u.get_name());
  const NumericFunction J(jac, names);
  double rho = 0;
  for (double share : {kStartShare, 0.2, 0.35, 0.65, 0.8}) {
    std::vector<double> at;
    for (std::size_t i = 0; i < n; ++i) at.push_back(box.lo[i] + share * box.width[i]);
    for (std::size_t j = 0; j < m.m(); ++j) at.push_back(input_centre(m, j));
    const std::vector<double> v = J(at);
    Eigen::MatrixXd A(n, n);
    for (std::size_t i = 0; i < n; ++i)
      for (std::size_t j = 0; j < n; ++j) A(i, j) = v[i * n + j];
    if (!A.allFinite()) continue;
    const Eigen::VectorXcd ev = Eigen::EigenSolver<Eigen::MatrixXd>(A, false).eigenvalues();
    for (Eigen::Index k = 0; k < ev.size(); ++k) rho = std::max(rho, std::abs(ev(k)));
  }
  return rho > 1e-9 && std::isfinite(rho) ? rho : 1.0;
}

// Each input: its box centre plus a quarter-width sine of period 2 pi * 5 / rho (inputs
// without a box: constant u0).
std::string input_text(const Model& m, double rho) {
  std::vector<std::string> parts;
  for (std::size_t j = 0; j < m.m(); ++j) {
    const double c = input_centre(m, j);
    if (!m.domain.count(m.inputs[j].get_name())) {
      parts.push_back(fmt::format("{:.6g}", c));
      continue;
    }
    const Interval b = m.box(m.inputs[j]);
    const double amp = 0.25 * (b.hi.to_double() - b.lo.to_double());
    const std::string wave = fmt::format("{:.6g}*sin({:.6g}*t{})", amp, rho / 5,
                                         j == 0 ? std::string() : fmt::format(" + {}", j));
    parts.push_back(c == 0 ? wave : fmt::format("{:.6g} + {}", c, wave));
  }
  return parts.empty() ? "0" : fmt::format("{}", fmt::join(parts, ", "));
}

struct RunJudgement {
  TrialVerdict verdict;
  double final_error;  // share of the box
  std::string why;     // for a failed or inconclusive run
};

double box_error(const std::vector<double>& x, const std::vector<double>& xh, const Box& box) {
  double e = 0;
  for (std::size_t i = 0; i < x.size(); ++i)
    e = std::max(e, std::fabs(x[i] - xh[i]) / box.width[i]);
  return e;
}

bool outside(const std::vector<double>& x, const Box& box, double slack) {
  for (std::size_t i = 0; i < x.size(); ++i)
    if (x[i] < box.lo[i] - slack * box.width[i] || x[i] > box.lo[i] + (1 + slack) * box.width[i])
      return true;
  return false;
}

RunJudgement judge(const SimulationResult& r, const Box& box, double t_end) {
  std::size_t valid = r.t.size();  // samples before the plant left its box
  for (std::size_t k = 0; k < r.t.size(); ++k)
    if (outside(r.x[k], box, kPlantSlack)) {
      valid = k;
      break;
    }
  for (std::size_t k = 0; k < valid; ++k)
    if (outside(r.xh[k], box, kEstimateSlack))
      return {
          TrialVerdict::failed, 0,
          fmt::format("the estimate left the box by more than two widths at t = {:.3g}", r.t[k])};
  const bool plant_ok = valid == r.t.size();
  if (plant_ok && !r.diverged.empty() && r.diverged.find("the plant") == std::string::npos)
    return {TrialVerdict::failed, 0, r.diverged.substr(r.diverged.find(':') + 2)};
  if (valid < 2) return {TrialVerdict::inconclusive, 0, "the plant left the box at once"};
  const double t_valid = r.t[valid - 1];
  double final_error = 0;
  for (std::size_t k = 0; k < valid; ++k)
    if (r.t[k] >= (1 - kFinalWindow) * t_valid)
      final_error = std::max(final_error, box_error(r.x[k], r.xh[k], box));
  if (final_error < kConverged && final_error < kReduction * kInitialError)
    return {TrialVerdict::passed, final_error, ""};
  if (final_error < kInitialError)
    return {plant_ok ? TrialVerdict::slow : TrialVerdict::inconclusive, final_error,
            plant_ok
                ? fmt::format("its error fell, but only to {:.3g} % of the box", 100 * final_error)
                : fmt::format("the plant left the box at t = {:.3g}", r.t[valid])};
  if (!plant_ok || t_valid < (1 - kFinalWindow) * t_end)
    return {TrialVerdict::inconclusive, final_error,
            fmt::format("the plant left the box at t = {:.3g}", r.t[valid])};
  return {
      TrialVerdict::failed, final_error,
      fmt::format("its error did not fall ({:.3g} % of the box at the end)", 100 * final_error)};
}

SimulationResult run(const Analysis& a, const ObserverSpec& spec, const Box& box,
                     SimulationOptions opt, double sign) {
  opt.x0.clear();
  opt.xhat0.clear();
  for (std::size_t i = 0; i < a.model.n(); ++i) {
    const double x0 = box.lo[i] + kStartShare * box.width[i];
    const double up = (i % 2 == 0 ? sign : -sign) * kInitialError * box.width[i];
    opt.x0.push_back(x0);
    opt.xhat0.push_back(x0 + up);
  }
  return run_closed_loop(a, spec, opt, nullptr);
}

}  // namespace

TrialOutcome closed_loop_trial(const Analysis& a, const ObserverSpec& spec) {
  const Model& m = a.model;
  const Box box = state_box(m);
  const GiNaC::exmap params = parameter_values(m, spec);
  const double rho = time_scale(m, params, box);
  SimulationOptions opt;
  opt.method = spec.method;
  opt.u_text = input_text(m, rho);
  opt.t_end = kHorizonSpans / rho;
  opt.dt = kStepShare / rho;
  // Half the observer's own RK4 limit when its error dynamics are faster than the plant's.
  if (spec.largest_safe_step > 0) opt.dt = std::min(opt.dt, spec.largest_safe_step / 2);
  if (spec.sampled_delay) opt.dt = spec.sampled_delay->sample_period;
  opt.t_end = std::min(opt.t_end, opt.dt * static_cast<double>(kMaxSteps));
  TrialOutcome out;
  out.setup = fmt::format(
      "closed-loop trial (sampled: 2 runs from errors of {:g} % of the box, u = {}, t in [0, "
      "{:.3g}], RK4 step {:.3g})",
      100 * kInitialError, opt.u_text, opt.t_end, opt.dt);
  // The runs' verdicts combine worst first: failed, slow, inconclusive, passed.
  const auto severity = [](TrialVerdict v) {
    return v == TrialVerdict::failed         ? 3
           : v == TrialVerdict::slow         ? 2
           : v == TrialVerdict::inconclusive ? 1
                                             : 0;
  };
  double worst = 0;
  out.verdict = TrialVerdict::passed;
  for (double sign : {1.0, -1.0}) {
    SimulationResult r = run(a, spec, box, opt, sign);
    RunJudgement j = judge(r, box, opt.t_end);
    if (j.verdict == TrialVerdict::failed && r.diverged.find("finite") != std::string::npos &&
        !spec.sampled_delay) {  // a step too long for the observer's own speed: once more
      SimulationOptions fine = opt;
      fine.dt = opt.dt / 10;
      fine.t_end = std::min(opt.t_end, fine.dt * static_cast<double>(kMaxSteps));
      j = judge(run(a, spec, box, fine, sign), box, fine.t_end);
    }
    worst = std::max(worst, j.final_error);
    if (severity(j.verdict) > severity(out.verdict)) {
      out.verdict = j.verdict;
      out.text = j.why;
    }
    if (j.verdict == TrialVerdict::failed) return out;
  }
  if (out.verdict == TrialVerdict::passed)
    out.text = fmt::format("converged, final error {:.3g} % of the box", 100 * worst);
  return out;
}

}  // namespace obsynth
