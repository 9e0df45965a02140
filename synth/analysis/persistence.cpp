#include "analysis/persistence.hpp"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>

#include "analysis/observability.hpp"
#include "analysis/triangular_form.hpp"
#include "front/parse.hpp"
#include "symbolic/dag.hpp"
#include "symbolic/expr_print.hpp"
#include "symbolic/symbolic.hpp"
#include "symbolic/zero_test.hpp"

namespace obsynth {

using GiNaC::ex;

namespace {

// The blocks when the outputs are states in increasing order, the first being x1: y_i = x_{s_i},
// 0 = s_1 < ... < s_p, block i = x_{s_i}..x_{s_{i+1}-1}. Or the reason they are not.
std::optional<std::vector<std::size_t>> blocks_in_x(const Model& m, std::string& why) {
  std::vector<std::size_t> starts;
  for (std::size_t i = 0; i < m.p(); ++i) {
    const auto it = std::find_if(m.states.begin(), m.states.end(),
                                 [&](const GiNaC::symbol& x) { return (m.h[i] - x).is_zero(); });
    const auto s = static_cast<std::size_t>(it - m.states.begin());
    if (it == m.states.end() || (i == 0 && s != 0) || (i > 0 && s <= starts.back())) {
      why = m.p() == 1
                ? fmt::format("the output is not the first state (y = {}, the form needs y = {})",
                              to_string(m.h[0]), m.states[0].get_name())
                : fmt::format(
                      "output {} (y{} = {}) is not a state after the previous outputs' "
                      "(the form in x needs y_1 = x1 and each y_i a later state, starting "
                      "its block)",
                      i + 1, i + 1, to_string(m.h[i]));
      return std::nullopt;
    }
    starts.push_back(s);
  }
  std::vector<std::size_t> blocks;
  for (std::size_t i = 0; i < starts.size(); ++i)
    blocks.push_back((i + 1 < starts.size() ? starts[i + 1] : m.n()) - starts[i]);
  return blocks;
}

}  // namespace

std::optional<TriangularInX> triangular_in_x(const Model& m, std::string* why) {
  auto fail = [&](const std::string& s) -> std::optional<TriangularInX> {
    if (why) *why = s;
    return std::nullopt;
  };
  const std::size_t n = m.n();
  if (n < 1) return fail("no states");
  std::string why_blocks;
  const auto blocks = blocks_in_x(m, why_blocks);
  if (!blocks) return fail(why_blocks);
  const SampleBoxes boxes = m.sample_boxes();
  const ExVec F = m.field();
  const auto& B = *blocks;
  TriangularInX t;
  t.blocks = m.p() == 1 ? std::vector<std::size_t>{} : B;
  for (std::size_t i = 0; i < n; ++i) {
    // Row i may read the states of its level or below, and the next state of its block.
    const bool last = level_of(B, i) == B[block_of(B, i)];
    for (std::size_t j = 0; j < n; ++j)
      if (level_of(B, j) > level_of(B, i) && !(j == i + 1 && !last) &&
          !is_zero_verdict(zero_test(F[i].diff(m.states[j]), boxes)))
        return fail(m.p() == 1 ? fmt::format("row {} depends on {} (beyond the superdiagonal)",
                                             i + 1, m.states[j].get_name())
                               : fmt::format("row {} (level {}) depends on {} (level {}): not "
                                             "block triangular",
                                             i + 1, level_of(B, i), m.states[j].get_name(),
                                             level_of(B, j)));
    if (i + 1 == n) {
      t.phi.push_back(F[i]);
      break;
    }
    if (last) {  // the superdiagonal is zero between blocks
      t.a.push_back(0);
      t.phi.push_back(F[i]);
      continue;
    }
    const ex a = simplify(F[i].diff(m.states[i + 1]));
    if (depends_on(a, m.states))
      return fail(fmt::format("row {}: the coefficient of {} is {}, which depends on the state",
                              i + 1, m.states[i + 1].get_name(), to_string(a)));
    t.a.push_back(a);
    t.phi.push_back(simplify(F[i] - a * m.states[i + 1]));
  }
  if (why) why->clear();
  return t;
}

namespace {

// A witness of how fast |J| grows near the zero set of its denominator factor f (in x): when
// f is linear in one variable s with its root r in the box, the largest |J| over 16 sampled
// points of the box with s moved to r + 1 % and r + 0.01 % of s's box width (towards the
// inside). Growth by ~100x between the two is the 1 / distance of a pole. Empty otherwise.
std::string growth_near_zero(const ex& J, const ex& f, const Model& m, const SampleBoxes& boxes) {
  const auto vars = symbols_in(f);
  if (vars.size() != 1 || !f.info(GiNaC::info_flags::rational_polynomial)) return "";
  const GiNaC::symbol& s = vars[0];
  const ex p = GiNaC::expand(f);
  if (p.degree(s) != 1) return "";
  const GiNaC::numeric r =
      -GiNaC::ex_to<GiNaC::numeric>(p.coeff(s, 0)) / GiNaC::ex_to<GiNaC::numeric>(p.coeff(s, 1));
  const Interval b = boxes.box(s);
  if (r < b.lo || r > b.hi) return "";
  const auto points = sample_points(m.all_symbols(), boxes, 16, 0x6b74);
  std::vector<std::string> parts;
  for (const GiNaC::numeric& fraction : {GiNaC::numeric(1, 100), GiNaC::numeric(1, 10000)}) {
    GiNaC::numeric d = (b.hi - b.lo) * fraction;
    if (r + d > b.hi) d = -d;
    double worst = 0;
    for (auto pt : points) {
      pt[s] = r + d;
      GiNaC::numeric v;
      if (evaluate_real(J, pt, 30, v)) worst = std::max(worst, std::abs(v.to_double()));
    }
    parts.push_back(
        fmt::format("max |.| = {:.3g} at {} = {:.4g}", worst, s.get_name(), (r + d).to_double()));
  }
  return fmt::format(" ({} box points with {} moved near the zero {}: {})", points.size(),
                     s.get_name(), to_string(r), fmt::join(parts, ", "));
}

}  // namespace

PhiLipschitz phi_lipschitz_on_box(const Model& m, const std::vector<GiNaC::symbol>& z,
                                  const ExVec& phi, const ExVec& z_of_x) {
  GiNaC::exmap at_x;
  for (std::size_t i = 0; i < z_of_x.size() && i < z.size(); ++i) at_x[z[i]] = z_of_x[i];
  const SampleBoxes boxes = m.sample_boxes();
  std::vector<std::string> unknown;
  std::size_t entries = 0;
  for (std::size_t i = 0; i < phi.size(); ++i)
    for (std::size_t j = 0; j < z.size(); ++j) {
      const ex J = GiNaC::normal(phi[i].diff(z[j]));
      if (J.is_zero()) continue;
      ++entries;
      for (const auto& f : dependent_factors(GiNaC::denom(J), z)) {
        const ex fx = f.subs(at_x);
        const BoxZeros zb = zeros_in_box(fx, boxes);
        if (zb.kind == BoxZeros::never) continue;
        const std::string entry = fmt::format("d phi_{}/d z{} = {}", i + 1, j + 1, to_string(J));
        if (zb.kind == BoxZeros::unknown) {
          unknown.push_back(fmt::format("{}: denominator {} not proved nonzero ({})", entry,
                                        to_string(f), zb.detail));
          continue;
        }
        const std::string where =
            z_of_x.empty() ? std::string() : fmt::format(", i.e. {} = 0 in x", to_string(fx));
        return {PhiLipschitz::fails,
                fmt::format("phi is not Lipschitz in z on the domain box: {} has the denominator "
                            "{}, which vanishes in the box{} ({}); no Lipschitz constant holds "
                            "there{}",
                            entry, to_string(f), where, zb.detail,
                            growth_near_zero(J.subs(at_x), fx, m, boxes))};
      }
    }
  if (!unknown.empty())
    return {PhiLipschitz::unknown,
            fmt::format("phi Lipschitz in z on the domain box not proved: {}",
                        fmt::join(unknown, "; "))};
  return {PhiLipschitz::proved,
          fmt::format("phi is Lipschitz in z on the domain box: the {} nonzero entries of "
                      "d phi/d z have no denominator vanishing there (proved)",
                      entries)};
}

namespace {

using Mat = Eigen::MatrixXd;

struct InputPath {
  NumericFunction u_of_t;
  NumericFunction a_of_u;
  std::size_t n = 0;
  std::vector<std::size_t> blocks;  // {n} for one output
  Mat A(double t) const {
    const std::vector<double> u = u_of_t({t});
    const std::vector<double> a = a_of_u(u);
    Mat M = Mat::Zero(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(n));
    for (std::size_t i = 0; i + 1 < n; ++i)
      M(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(i + 1)) = a[i];
    return M;
  }
};

InputPath make_path(const Model& m, const TriangularInX& t, const std::string& input_text) {
  GiNaC::symbol ts("t");
  ExVec u_of_t = parse_expression_list(input_text, "--input", {ts});
  if (u_of_t.size() != m.m())
    throw UserError(SourceLoc{},
                    fmt::format("--input needs {} expression{} in t (one per input), got {}", m.m(),
                                m.m() == 1 ? "" : "s", u_of_t.size()));
  GiNaC::exmap params;
  for (const auto& p : m.free_params()) {
    const Interval b = m.box(p);
    params[p] = (b.lo + b.hi) / 2;
  }
  ExVec a = t.a;
  for (auto& e : a) e = e.subs(params);
  if (a.empty()) a.push_back(0);  // n = 1: no superdiagonal
  std::vector<std::string> un;
  for (const auto& s : m.inputs) un.push_back(s.get_name());
  InputPath p{NumericFunction(u_of_t, {"t"}), NumericFunction(a, un), m.n(),
              t.blocks.empty() ? std::vector<std::size_t>{m.n()} : t.blocks};
  return p;
}

// C^T C: C selects the first coordinate of every block.
Mat CtC(const InputPath& path) {
  const auto N = static_cast<Eigen::Index>(path.n);
  Mat M = Mat::Zero(N, N);
  for (const std::size_t s : block_starts(path.blocks))
    M(static_cast<Eigen::Index>(s), static_cast<Eigen::Index>(s)) = 1;
  return M;
}

// Psi' = -theta Psi - A^T Psi - Psi A + C^T C, Psi(0) = 0, checked on [t0, horizon].
PersistenceAtTheta at_theta(const InputPath& path, double theta, double horizon, double t0) {
  PersistenceAtTheta r;
  r.theta = theta;
  const std::size_t n = path.n;
  const Mat Q = CtC(path);
  auto rhs = [&](double t, const Mat& P) {
    const Mat A = path.A(t);
    return Mat(-theta * P - A.transpose() * P - P * A + Q);
  };
  const double dt_max = std::min(horizon / 20000.0, 0.02 / theta);
  const auto steps = static_cast<std::size_t>(std::ceil(horizon / dt_max));
  const double dt = horizon / static_cast<double>(steps);
  const std::size_t check_every = std::max<std::size_t>(1, steps / 400);
  Mat P = Mat::Zero(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(n));
  r.min_psi_eig = std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k < steps; ++k) {
    const double t = static_cast<double>(k) * dt;
    const Mat k1 = rhs(t, P);
    const Mat k2 = rhs(t + dt / 2, P + dt / 2 * k1);
    const Mat k3 = rhs(t + dt / 2, P + dt / 2 * k2);
    const Mat k4 = rhs(t + dt, P + dt * k3);
    P += dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
    const double t1 = t + dt;
    if (t1 < t0 - 1e-12 || ((k + 1) % check_every != 0 && k + 1 != steps)) continue;
    const Mat S = (P + P.transpose()) / 2;
    const Eigen::VectorXd d = S.diagonal();
    const double dmax = d.maxCoeff();
    if (!(d.minCoeff() > 1e-13 * dmax)) {
      if (r.gamma_invertible) r.worst_t = t1;
      r.gamma_invertible = false;
    } else {
      for (Eigen::Index i = 0; i < d.size(); ++i)
        for (Eigen::Index j = 0; j < d.size(); ++j)
          if (level_of(path.blocks, static_cast<std::size_t>(j)) <=
              level_of(path.blocks, static_cast<std::size_t>(i)))
            r.gamma = std::max(r.gamma, d(i) / d(j));
    }
    const Eigen::SelfAdjointEigenSolver<Mat> es(S);
    const double lmin = es.eigenvalues().minCoeff(), lmax = es.eigenvalues().maxCoeff();
    r.min_psi_eig = std::min(r.min_psi_eig, lmin);
    if (!(lmin > 1e-13 * lmax)) {
      if (r.psi_positive && r.gamma_invertible) r.worst_t = t1;
      r.psi_positive = false;
      continue;
    }
    // smallest alpha with Gamma <= alpha Psi: lambda_max(L^-1 Gamma L^-T), Psi = L L^T.
    const Eigen::LLT<Mat> llt(S);
    Mat G = d.asDiagonal();
    const Mat X = llt.matrixL().solve(G);
    const Mat Y = llt.matrixL().solve(X.transpose());
    const double alpha =
        Eigen::SelfAdjointEigenSolver<Mat>((Y + Y.transpose()) / 2).eigenvalues().maxCoeff();
    if (alpha > r.alpha && r.psi_positive && r.gamma_invertible) r.worst_t = t1;
    r.alpha = std::max(r.alpha, alpha);
  }
  if (!r.psi_positive || !r.gamma_invertible) {
    r.alpha = std::numeric_limits<double>::infinity();
    if (!r.gamma_invertible) r.gamma = std::numeric_limits<double>::infinity();
  }
  return r;
}

// lambda_min of G(u, a, b) = int_a^b Phi(t,a)^T C^T C Phi(t,a) dt.
double gramian_min_eig(const InputPath& path, double a, double b, double dt_max) {
  const std::size_t n = path.n;
  const auto N = static_cast<Eigen::Index>(n);
  const Mat Q = CtC(path);
  const auto steps =
      std::max<std::size_t>(1, static_cast<std::size_t>(std::ceil((b - a) / dt_max)));
  const double dt = (b - a) / static_cast<double>(steps);
  Mat Phi = Mat::Identity(N, N), G = Mat::Zero(N, N);
  // Joint RK4 on (Phi, G): Phi' = A Phi, G' = Phi^T Q Phi.
  auto dPhi = [&](double t, const Mat& F) { return Mat(path.A(t) * F); };
  for (std::size_t k = 0; k < steps; ++k) {
    const double t = a + static_cast<double>(k) * dt;
    const Mat F1 = Phi, K1 = dPhi(t, F1);
    const Mat F2 = Phi + dt / 2 * K1, K2 = dPhi(t + dt / 2, F2);
    const Mat F3 = Phi + dt / 2 * K2, K3 = dPhi(t + dt / 2, F3);
    const Mat F4 = Phi + dt * K3, K4 = dPhi(t + dt, F4);
    G += dt / 6 *
         (F1.transpose() * Q * F1 + 2 * F2.transpose() * Q * F2 + 2 * F3.transpose() * Q * F3 +
          F4.transpose() * Q * F4);
    Phi += dt / 6 * (K1 + 2 * K2 + 2 * K3 + K4);
  }
  const Mat S = (G + G.transpose()) / 2;
  return Eigen::SelfAdjointEigenSolver<Mat>(S).eigenvalues().minCoeff();
}

std::string num(double v) {
  if (std::isinf(v)) return "inf";
  return fmt::format("{:.4g}", v);
}

// The observability Gramians' smallest eigenvalues: over [0, horizon], and the smallest over
// eleven windows of length r.window ending in [t0, horizon].
void gramians(const InputPath& path, double horizon, PersistenceResult& r) {
  const double dt_max = horizon / 20000.0;
  r.gramian_min_eig = gramian_min_eig(path, 0, horizon, dt_max);
  r.window_gramian_min_eig = std::numeric_limits<double>::infinity();
  for (int k = 0; k <= 10; ++k) {
    const double t = r.t0 + (horizon - r.t0) * k / 10.0;
    r.window_gramian_min_eig =
        std::min(r.window_gramian_min_eig, gramian_min_eig(path, t - r.window, t, dt_max));
  }
}

// i): Gamma invertible and Psi positive definite for every theta, and alpha(theta)/theta
// decreasing, at least like theta^-1/2 over the range.
bool condition_i(const std::vector<PersistenceAtTheta>& by_theta) {
  bool ok = !by_theta.empty();
  for (const auto& b : by_theta) ok = ok && b.gamma_invertible && b.psi_positive;
  if (ok && by_theta.size() >= 2) {
    for (std::size_t k = 1; k < by_theta.size(); ++k)
      ok = ok && by_theta[k].alpha / by_theta[k].theta <=
                     1.05 * by_theta[k - 1].alpha / by_theta[k - 1].theta;
    const auto& lo = by_theta.front();
    const auto& hi = by_theta.back();
    ok = ok && hi.alpha / hi.theta <= lo.alpha / lo.theta * std::sqrt(lo.theta / hi.theta);
  }
  return ok;
}

// ii): Gamma_ii / Gamma_jj bounded: finite, and at the largest theta no larger than before.
bool condition_ii(const std::vector<PersistenceAtTheta>& by_theta) {
  bool ok = !by_theta.empty();
  double gmax = 0;
  for (std::size_t k = 0; k < by_theta.size(); ++k) {
    const auto& b = by_theta[k];
    ok = ok && std::isfinite(b.gamma);
    if (k + 1 == by_theta.size() && k > 0) ok = ok && b.gamma <= 1.0001 * gmax;
    gmax = std::max(gmax, b.gamma);
  }
  return ok;
}

// Which condition failed, and where.
std::string failure_text(const PersistenceResult& r) {
  std::string failed;
  if (!r.condition_i) {
    for (const auto& b : r.by_theta)
      if (!b.gamma_invertible || !b.psi_positive) {
        failed = fmt::format(
            "i) fails: at theta = {} Gamma{} is singular at t = {:.4g} (min eigenvalue of Psi "
            "{:.3g})",
            num(b.theta), b.gamma_invertible ? " is invertible but Psi" : "", b.worst_t,
            b.min_psi_eig);
        break;
      }
    if (failed.empty())
      failed =
          fmt::format("i) fails: alpha(theta)/theta does not decrease to 0 over theta in [{}, {}]",
                      num(r.by_theta.front().theta), num(r.by_theta.back().theta));
  } else if (!r.condition_ii) {
    failed = "ii) fails: Gamma_ii / Gamma_jj (j <= i) is unbounded or grows with theta";
  }
  return failed;
}

}  // namespace

PersistenceResult check_persistence(const Model& m, const PersistenceOptions& opt) {
  PersistenceResult r;
  r.input_text = opt.input_text;
  r.horizon = opt.horizon;
  if (!(opt.horizon > 0) || !std::isfinite(opt.horizon))
    throw UserError(SourceLoc{}, "--horizon must be a positive number");
  r.t0 = opt.t0 >= 0 ? opt.t0 : opt.horizon / 2;
  if (r.t0 >= opt.horizon)
    throw UserError(SourceLoc{}, "the checked interval [t0, horizon] is empty");
  r.window = opt.horizon - r.t0;
  std::string why;
  auto form = triangular_in_x(m, &why);
  std::string where = "in x";
  if (form) r.lipschitz = phi_lipschitz_on_box(m, m.states, form->phi, {});
  if (!form) {
    // The triangular form in other coordinates (z a permutation of x, or z = (h, L_f h, ...)):
    // only A(u) enters Psi, Gamma and the Gramian.
    std::string why_t;
    std::optional<TriangularForm> t;
    if (m.p() == 1)
      t = triangular_form(m, &why_t);
    else if (opt.indices.empty())
      why_t =
          "the observability indices are needed for the block form (obsynth check passes the "
          "analysis' indices)";
    else
      t = block_triangular_form(m, opt.indices, &why_t);
    if (t) {
      form = TriangularInX{t->a, t->phi, t->blocks};
      r.lipschitz = phi_lipschitz_on_box(m, t->z, t->phi, t->z_of_x);
      where = t->coordinates == TriangularForm::Coordinates::states
                  ? "in the states reordered"
                  : fmt::format("in the coordinates z = {} = [{}]",
                                m.p() == 1 ? "(h, L_f h, ...)"
                                           : "(h_i, L_f h_i, ..., L_f^{k_i-1} h_i) per output",
                                fmt::join(to_strings(t->z_of_x), ", "));
    } else {
      r.reason = fmt::format(
          "the model is not in seed 002's form z' = A(u) z + phi(u, z), y = z1 in x ({}), nor "
          "in other coordinates ({})",
          why, why_t);
      r.verdict = "not decided: " + r.reason;
      return r;
    }
  }
  r.applicable = true;
  std::vector<std::string> as;
  for (const auto& a : form->a) as.push_back(to_string(a));
  r.reason =
      fmt::format("in seed 002's form {}, superdiagonal a(u) = [{}]", where, fmt::join(as, ", "));
  if (!form->blocks.empty()) {  // p > 1: say which rows C reads
    std::vector<std::string> e;
    for (const std::size_t s : block_starts(form->blocks)) e.push_back(fmt::format("e_{}", s + 1));
    r.reason += fmt::format(" (blocks of sizes {}, zero between them), C = [{}]^T",
                            fmt::join(form->blocks, ", "), fmt::join(e, ", "));
  }
  const InputPath path = make_path(m, *form, opt.input_text);
  std::vector<double> thetas = opt.thetas;
  std::sort(thetas.begin(), thetas.end());
  for (double th : thetas) {
    if (!(th > 0)) throw UserError(SourceLoc{}, "theta values must be positive");
    r.by_theta.push_back(at_theta(path, th, opt.horizon, r.t0));
  }
  gramians(path, opt.horizon, r);
  r.condition_i = condition_i(r.by_theta);
  r.condition_ii = condition_ii(r.by_theta);
  r.persistent = r.condition_i && r.condition_ii;
  r.verdict =
      r.persistent
          ? fmt::format(
                "strongly persistent on [{:.4g}, {:.4g}] for theta in [{}, {}] (numerical "
                "check along the input, sampled in t and theta)",
                r.t0, r.horizon, num(r.by_theta.front().theta), num(r.by_theta.back().theta))
          : "not strongly persistent (numerical check along the input): " + failure_text(r);
  // Persistence is a property of A(u) alone; the Theorem also needs phi Lipschitz, and without
  // it no input makes the observer converge by the Theorem.
  if (r.lipschitz.kind == PhiLipschitz::fails)
    r.verdict += "; but seed 002's Theorem does not apply to this model whatever the input: " +
                 r.lipschitz.text;
  else if (r.lipschitz.kind == PhiLipschitz::unknown)
    r.verdict += "; seed 002's Theorem also needs phi Lipschitz in z, which is not proved: " +
                 r.lipschitz.text;
  return r;
}

nlohmann::ordered_json persistence_json(const PersistenceResult& r) {
  auto number = [](double v) -> nlohmann::ordered_json {
    if (std::isfinite(v)) return v;
    return nullptr;  // inf: JSON has no infinity
  };
  nlohmann::ordered_json j;
  j["input"] = r.input_text;
  j["applicable"] = r.applicable;
  j["form"] = r.reason;
  j["horizon"] = r.horizon;
  j["t0"] = r.t0;
  if (r.applicable) {
    nlohmann::ordered_json rows = nlohmann::ordered_json::array();
    for (const auto& b : r.by_theta)
      rows.push_back({{"theta", b.theta},
                      {"gamma_invertible", b.gamma_invertible},
                      {"psi_positive_definite", b.psi_positive},
                      {"alpha", number(b.alpha)},
                      {"alpha_over_theta", number(b.alpha / b.theta)},
                      {"gamma", number(b.gamma)},
                      {"min_eig_psi", b.min_psi_eig},
                      {"worst_t", b.worst_t}});
    j["by_theta"] = rows;
    j["gramian_min_eig"] = r.gramian_min_eig;
    j["window"] = r.window;
    j["window_gramian_min_eig"] = r.window_gramian_min_eig;
    j["condition_i"] = r.condition_i;
    j["condition_ii"] = r.condition_ii;
    j["strongly_persistent"] = r.persistent;
    j["phi_lipschitz"] = r.lipschitz.kind == PhiLipschitz::proved  ? "proved"
                         : r.lipschitz.kind == PhiLipschitz::fails ? "fails"
                                                                   : "unknown";
    j["phi_lipschitz_text"] = r.lipschitz.text;
  } else {
    j["strongly_persistent"] = nullptr;
  }
  j["verdict"] = r.verdict;
  j["kind"] = "sampled";
  return j;
}

std::string render_persistence(const PersistenceResult& r, const std::string& format) {
  const bool md = format == "markdown", tex = format == "latex";
  auto esc = [&](const std::string& s) {
    if (!tex) return s;
    std::string o;
    for (char c : s) {
      if (c == '_' || c == '&' || c == '%' || c == '#' || c == '$' || c == '{' || c == '}')
        o += '\\';
      if (c == '^') {
        o += "\\^{}";
        continue;
      }
      o += c;
    }
    return o;
  };
  std::string out;
  const std::string title = "Strong persistence of the input (seed 002)";
  out += md    ? "\n## " + title + "\n\n"
         : tex ? "\n\\section*{" + esc(title) + "}\n"
               : "\n" + title + "\n";
  auto line = [&](const std::string& k, const std::string& v) {
    if (md)
      out += fmt::format("- {}: {}\n", k, v);
    else if (tex)
      out += fmt::format("{}: {}\\\\\n", esc(k), esc(v));
    else
      out += fmt::format("  {}: {}\n", k, v);
  };
  line("input", r.input_text);
  line("form", r.reason);
  if (r.applicable) {
    line("checked on", fmt::format("t in [{:.4g}, {:.4g}]", r.t0, r.horizon));
    line("Gramian (6) over [0, horizon]", fmt::format("lambda_min = {:.4g}", r.gramian_min_eig));
    line(fmt::format("Gramian over windows of length {:.4g}", r.window),
         fmt::format("min lambda_min = {:.4g}", r.window_gramian_min_eig));
    const std::string head = "theta | Gamma invertible | Psi > 0 | alpha | alpha/theta | gamma";
    if (md)
      out +=
          "\n| theta | Gamma invertible | Psi > 0 | alpha | alpha/theta | gamma "
          "|\n|---|---|---|---|---|---|\n";
    else if (tex)
      out +=
          "\\begin{tabular}{rrrrrr}\n$\\theta$ & $\\Gamma$ invertible & $\\Psi>0$ & $\\alpha$ & "
          "$\\alpha/\\theta$ & $\\gamma$\\\\\n";
    else
      out += "  " + head + "\n";
    for (const auto& b : r.by_theta) {
      const std::string cells[6] = {num(b.theta),
                                    b.gamma_invertible ? "yes" : "no",
                                    b.psi_positive ? "yes" : "no",
                                    num(b.alpha),
                                    num(b.alpha / b.theta),
                                    num(b.gamma)};
      if (md)
        out += fmt::format("| {} |\n", fmt::join(cells, cells + 6, " | "));
      else if (tex)
        out += fmt::format("{}\\\\\n", fmt::join(cells, cells + 6, " & "));
      else
        out += fmt::format("  {}\n", fmt::join(cells, cells + 6, " | "));
    }
    if (tex) out += "\\end{tabular}\\\\\n";
    if (md) out += "\n";
    line("condition i)", r.condition_i ? "holds (sampled)" : "fails");
    line("condition ii)", r.condition_ii ? "holds (sampled)" : "fails");
    line("phi Lipschitz in z (the Theorem's other hypothesis)", r.lipschitz.text);
  }
  line("verdict", r.verdict);
  return out;
}

}  // namespace obsynth
