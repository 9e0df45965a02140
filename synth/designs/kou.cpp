#include "designs/kou.hpp"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <map>

#include "certify/enclosure.hpp"
#include "designs/options.hpp"
#include "designs/thau.hpp"
#include "emit/dag.hpp"
#include "symbolic/expr_print.hpp"
#include "symbolic/symbolic.hpp"

namespace obsynth {

using GiNaC::ex;
using GiNaC::numeric;
using namespace lyapunov_tools;

namespace {

// The search stops improving past this guaranteed decay rate of |e| (1/s): beyond it, higher
// gains buy rate the certificate does not need.
constexpr double kRateCap = 0.25;
constexpr std::size_t kSearchSamples = 384;
constexpr int kCertifyRounds = 4;
// No new round once this many candidates were evaluated (a deterministic budget, unlike time).
constexpr std::size_t kCertifyEvaluations = 6000;
constexpr double kMaxPole = 20;  // linearisation pole sets tried: |pole| <= kMaxPole
constexpr std::size_t kReportSamples = 4096;

using Mat = Eigen::MatrixXd;
using Idx = Eigen::Index;

struct Result {
  std::string not_applicable;
  std::size_t n = 0, p = 0;
  GiNaC::matrix L, P;  // exact rationals
  bool user_L = false, user_P = false;
  std::size_t tried = 0;
  std::string origin;          // how L and P were found
  int rounds = 1;              // search-and-certify rounds
  double sampled_max_eig = 0;  // max over samples of lambda_max(S)
  std::vector<double> sampled_worst;
  double sigma_max_P = 0, sigma_min_P = 0;
  certify::DefinitenessVerdict verdict;
  certify::Box box;
  bool holds = false, rigorous = false;
  // Guaranteed decay rate of |e| (from the rigorous or sampled eigenvalue bound).
  double rate() const { return -verdict.max_eigenvalue_bound / sigma_max_P; }
};

// J = dF/dx and H = dh/dx at points of the box, evaluated through the expression DAG.
struct Jacobians {
  std::vector<Mat> J, H;
};

Jacobians evaluate(const Model& m, const certify::Box& box,
                   const std::vector<std::vector<double>>& points) {
  const std::size_t n = m.n(), p = m.p();
  const ExVec F = m.field();
  std::vector<ex> out;
  for (std::size_t j = 0; j < n; ++j)
    for (std::size_t i = 0; i < n; ++i) out.push_back(F[i].diff(m.states[j]));
  for (std::size_t j = 0; j < n; ++j)
    for (std::size_t i = 0; i < p; ++i) out.push_back(m.h[i].diff(m.states[j]));
  std::vector<std::string> names;
  for (const auto& v : box.vars) names.push_back(v.get_name());
  const NumericFunction fn(out, names);
  Jacobians r;
  for (const auto& pt : points) {
    const auto v = fn(pt);
    Mat J(static_cast<Idx>(n), static_cast<Idx>(n)), H(static_cast<Idx>(p), static_cast<Idx>(n));
    for (std::size_t j = 0; j < n; ++j) {
      for (std::size_t i = 0; i < n; ++i)
        J(static_cast<Idx>(i), static_cast<Idx>(j)) = v[j * n + i];
      for (std::size_t i = 0; i < p; ++i)
        H(static_cast<Idx>(i), static_cast<Idx>(j)) = v[n * n + j * p + i];
    }
    r.J.push_back(J);
    r.H.push_back(H);
  }
  return r;
}

double lambda_max(const Mat& S) {
  return Eigen::SelfAdjointEigenSolver<Mat>(S, Eigen::EigenvaluesOnly).eigenvalues()(S.rows() - 1);
}

// max_k lambda_max(sym(P (J_k + L H_k))) / sigma_max(P), and where; +inf if P is not PD.
double score(const Jacobians& jac, const Mat& L, const Mat& P, std::size_t* worst = nullptr) {
  const Eigen::VectorXd ep =
      Eigen::SelfAdjointEigenSolver<Mat>(P, Eigen::EigenvaluesOnly).eigenvalues();
  if (!(ep(0) > 0) || !std::isfinite(ep(ep.size() - 1)))
    return std::numeric_limits<double>::infinity();
  double best = -std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k < jac.J.size(); ++k) {
    const Mat N = P * (jac.J[k] + L * jac.H[k]);
    const double v = lambda_max((N + N.transpose()) / 2);
    if (!std::isfinite(v)) return std::numeric_limits<double>::infinity();
    if (v > best) {
      best = v;
      if (worst) *worst = k;
    }
  }
  return best / ep(ep.size() - 1);
}

Mat P_of(const std::vector<double>& r, std::size_t n, std::size_t offset) {
  Mat R = Mat::Zero(static_cast<Idx>(n), static_cast<Idx>(n));
  std::size_t k = offset;
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = 0; j <= i; ++j) R(static_cast<Idx>(i), static_cast<Idx>(j)) = r[k++];
  return R * R.transpose();
}

void push_factor(const Mat& P, std::vector<double>& v) {
  Eigen::LLT<Mat> llt(P);
  const Mat R = llt.matrixL();
  for (Idx i = 0; i < P.rows(); ++i)
    for (Idx j = 0; j <= i; ++j) v.push_back(R(i, j));
}

std::optional<Mat> matrix_option(const DesignOptions& o, const std::string& name, std::size_t rows,
                                 std::size_t cols, bool allow_diagonal) {
  const auto v = real_list_option(o, name);
  if (v.empty()) return std::nullopt;
  Mat M = Mat::Zero(static_cast<Idx>(rows), static_cast<Idx>(cols));
  if (allow_diagonal && v.size() == rows) {
    for (std::size_t i = 0; i < rows; ++i)
      M(static_cast<Idx>(i), static_cast<Idx>(i)) = v[i].to_double();
  } else if (v.size() == rows * cols) {
    for (std::size_t i = 0; i < rows; ++i)
      for (std::size_t j = 0; j < cols; ++j)
        M(static_cast<Idx>(i), static_cast<Idx>(j)) = v[i * cols + j].to_double();
  } else {
    throw UserError(
        SourceLoc{},
        fmt::format("--{}: expected {} entries ({} x {} row-major{}), got {}", name, rows * cols,
                    rows, cols, allow_diagonal ? fmt::format(", or {} diagonal entries", rows) : "",
                    v.size()));
  }
  return M;
}

// Entries rounded to a multiple of 1/per_unit, exact.
GiNaC::matrix exact_matrix(const Mat& M, double per_unit) {
  GiNaC::matrix E(static_cast<unsigned>(M.rows()), static_cast<unsigned>(M.cols()));
  for (Idx i = 0; i < M.rows(); ++i)
    for (Idx j = 0; j < M.cols(); ++j)
      E(static_cast<unsigned>(i), static_cast<unsigned>(j)) = round_absolute(M(i, j), per_unit);
  return E;
}

GiNaC::matrix exact_option(const DesignOptions& o, const std::string& name, std::size_t rows,
                           std::size_t cols, bool allow_diagonal) {
  const auto v = real_list_option(o, name);
  GiNaC::matrix E(static_cast<unsigned>(rows), static_cast<unsigned>(cols));
  if (allow_diagonal && v.size() == rows && rows * cols != rows) {
    for (std::size_t i = 0; i < rows; ++i) E(i, i) = v[i];
  } else {
    for (std::size_t i = 0; i < rows; ++i)
      for (std::size_t j = 0; j < cols; ++j) E(i, j) = v[i * cols + j];
  }
  return E;
}

std::string point_text(const certify::Box& b, const std::vector<double>& pt) {
  std::vector<std::string> out;
  for (std::size_t k = 0; k < b.vars.size() && k < pt.size(); ++k)
    out.push_back(fmt::format("{} = {:.6g}", b.vars[k].get_name(), pt[k]));
  return fmt::format("{}", fmt::join(out, ", "));
}

// The symmetric part of P (dF/dx + L dh/dx), exact in L and P, symbolic in x, u, parameters.
GiNaC::matrix symmetric_part(const Model& m, const GiNaC::matrix& L, const GiNaC::matrix& P) {
  const std::size_t n = m.n(), p = m.p();
  const ExVec F = m.field();
  GiNaC::matrix M(static_cast<unsigned>(n), static_cast<unsigned>(n));
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = 0; j < n; ++j) {
      ex e = F[i].diff(m.states[j]);
      for (std::size_t k = 0; k < p; ++k) e += L(i, k) * m.h[k].diff(m.states[j]);
      M(i, j) = e;
    }
  const GiNaC::matrix N = P.mul(M);
  GiNaC::matrix S(static_cast<unsigned>(n), static_cast<unsigned>(n));
  for (unsigned i = 0; i < n; ++i)
    for (unsigned j = 0; j < n; ++j) S(i, j) = GiNaC::expand((N(i, j) + N(j, i)) / 2);
  return S;
}

constexpr std::size_t kMaxSearchStates = 4;

Result design(const Model& m, const DesignOptions& o) {
  Result r;
  const std::size_t n = m.n(), p = m.p();
  r.n = n;
  r.p = p;
  r.box = certify::model_box(m);
  const auto uL = matrix_option(o, "kou-gain", n, p, false);
  const auto uP = matrix_option(o, "kou-p", n, n, true);
  r.user_L = uL.has_value();
  r.user_P = uP.has_value();
  if (uP) {
    if (!uP->isApprox(uP->transpose(), 0))
      throw UserError(SourceLoc{}, "--kou-p: P must be symmetric");
    if (Eigen::SelfAdjointEigenSolver<Mat>(*uP).eigenvalues()(0) <= 0)
      throw UserError(SourceLoc{}, "--kou-p: P must be positive definite");
  }
  // The search certifies candidates by branch and bound of an n x n symmetric matrix over the
  // whole box; past kMaxSearchStates states it takes minutes (chain models, n = 5: > 60 s).
  if (!r.user_L && n > kMaxSearchStates) {
    r.not_applicable = fmt::format(
        "not searched: n = {} states > {}, where the certified search of L and P takes too "
        "long; give --kou-gain (and --kou-p) to check a chosen observer",
        n, kMaxSearchStates);
    return r;
  }
  std::vector<std::pair<double, double>> ranges;
  for (const auto& rg : r.box.ranges) ranges.emplace_back(rg.lo, rg.hi);
  auto search_points = box_samples(ranges, kSearchSamples);
  Jacobians jac = evaluate(m, r.box, search_points);

  // Linearisation at the expansion point (origin when in the box, else the centre).
  std::vector<double> star;
  for (std::size_t k = 0; k < r.box.vars.size(); ++k) {
    const auto& rg = r.box.ranges[k];
    bool is_param = true;
    for (const auto& x : m.states) is_param = is_param && !r.box.vars[k].is_equal(x);
    for (const auto& u : m.inputs) is_param = is_param && !r.box.vars[k].is_equal(u);
    star.push_back(!is_param && rg.lo <= 0 && 0 <= rg.hi ? 0.0 : (rg.lo + rg.hi) / 2);
  }
  const Jacobians lin = evaluate(m, r.box, {star});
  const Mat& A0 = lin.J[0];
  const Mat& C0 = lin.H[0];

  struct Candidate {
    Mat L, P;
    double score = std::numeric_limits<double>::infinity();
    std::string origin;
  };
  Candidate best;
  auto consider = [&](const Mat& L, const Mat& P, const std::string& origin) {
    ++r.tried;
    const double s = score(jac, L, P);
    if (s < best.score) best = {L, P, s, origin};
  };
  auto lyap_P = [&](const Mat& L) -> std::optional<Mat> {
    const auto P =
        solve_lyapunov(A0 + L * C0, Mat::Identity(static_cast<Idx>(n), static_cast<Idx>(n)));
    if (!P || Eigen::SelfAdjointEigenSolver<Mat>(*P).eigenvalues()(0) <= 0) return std::nullopt;
    return Mat(*P / Eigen::SelfAdjointEigenSolver<Mat>(*P).eigenvalues()(static_cast<Idx>(n) - 1));
  };
  const Mat I = Mat::Identity(static_cast<Idx>(n), static_cast<Idx>(n));
  std::vector<Mat> L_candidates;
  if (uL) {
    L_candidates.push_back(*uL);
  } else {
    L_candidates.push_back(Mat::Zero(static_cast<Idx>(n), static_cast<Idx>(p)));
    for (std::size_t i = 0; i < p; ++i)
      for (const auto& poles : candidate_pole_sets(n)) {
        if (-*std::min_element(poles.begin(), poles.end()) > kMaxPole) continue;
        const auto l = place_poles(A0, C0.row(static_cast<Idx>(i)), poles);
        if (!l) continue;
        Mat L = Mat::Zero(static_cast<Idx>(n), static_cast<Idx>(p));
        L.col(static_cast<Idx>(i)) = *l;
        L_candidates.push_back(L);
      }
  }
  for (const auto& L : L_candidates) {
    if (uP) {
      consider(L, *uP, "");
      continue;
    }
    consider(L, I, "P = I");
    if (const auto P = lyap_P(L))
      consider(L, *P, "P from the Lyapunov equation of the linearisation");
  }
  r.origin = r.user_L && r.user_P ? "L and P given" : best.origin;
  // Search and certify; when the enclosure refutes the candidate, its worst point joins the
  // samples and the search resumes from the candidate (up to kCertifyRounds rounds).
  for (int round = 0;; ++round) {
    // Refinement: Nelder-Mead on the free entries, the score capped at the decay rate kRateCap.
    if (!(r.user_L && r.user_P) && std::isfinite(best.score)) {
      std::vector<double> v;
      if (!uL)
        for (Idx i = 0; i < best.L.rows(); ++i)
          for (Idx j = 0; j < best.L.cols(); ++j) v.push_back(best.L(i, j));
      const std::size_t nl = v.size();
      if (!uP) push_factor(best.P, v);
      auto unpack = [&](const std::vector<double>& w, Mat& L, Mat& P) {
        L = uL ? *uL : Mat(static_cast<Idx>(n), static_cast<Idx>(p));
        if (!uL)
          for (std::size_t k = 0; k < nl; ++k)
            L(static_cast<Idx>(k / p), static_cast<Idx>(k % p)) = w[k];
        P = uP ? *uP : P_of(w, n, nl);
      };
      double scale = 1;
      for (double x : v) scale = std::max(scale, std::fabs(x));
      auto pack = [&](const Candidate& c) {
        std::vector<double> w;
        if (!uL)
          for (Idx i = 0; i < c.L.rows(); ++i)
            for (Idx j = 0; j < c.L.cols(); ++j) w.push_back(c.L(i, j));
        if (!uP) push_factor(c.P, w);
        return w;
      };
      auto refine = [&](const std::vector<double>& from,
                        const std::function<double(const Mat&, const Mat&, double)>& objective) {
        const auto w = nelder_mead(
            [&](const std::vector<double>& w) {
              ++r.tried;
              Mat L, P;
              unpack(w, L, P);
              return objective(L, P, score(jac, L, P));
            },
            from, 0.1 * scale, 200 * static_cast<int>(from.size() + 1));
        Candidate c;
        unpack(w, c.L, c.P);
        c.score = score(jac, c.L, c.P);
        return c;
      };
      // Phase 1: the most negative sampled eigenvalue (per sigma_max(P)), capped at kRateCap.
      Candidate c1 = refine(v, [](const Mat& L, const Mat&, double s) {
        return std::max(s, -kRateCap) + 1e-6 * L.squaredNorm();
      });
      if (std::max(c1.score, -kRateCap) < std::max(best.score, -kRateCap)) {
        c1.origin = best.origin;
        if (c1.origin.find("refined") == std::string::npos)
          c1.origin +=
              std::string(c1.origin.empty() ? "" : ", ") + "refined by Nelder-Mead on samples";
        best = c1;
      }
      // Phase 2, once certified on the samples: smaller gains, keeping at least half that rate.
      if (best.score < 0 && !uL) {
        const double keep = best.score / 2;
        Candidate c2 = refine(pack(best), [&](const Mat& L, const Mat&, double s) {
          return s > keep ? std::numeric_limits<double>::infinity() : L.squaredNorm();
        });
        if (c2.score <= keep && c2.L.squaredNorm() < best.L.squaredNorm()) {
          c2.origin = best.origin;
          if (c2.origin.find("gains reduced") == std::string::npos)
            c2.origin += std::string(c2.origin.empty() ? "" : ", ") +
                         "gains reduced keeping half the sampled rate";
          best = c2;
        }
      }
      r.origin = best.origin;
    }
    if (!std::isfinite(best.score)) {
      r.not_applicable = "no L, P candidate could be evaluated on the domain samples";
      return r;
    }
    if (r.origin.empty()) r.origin = r.user_L ? "L given, P searched" : "P given, L searched";
    // Exact L and P: as given, or rounded (L to 1e-3, P normalised to sigma_max 1, to 1e-6).
    r.L = uL ? exact_option(o, "kou-gain", n, p, false) : exact_matrix(best.L, 1e3);
    if (uP) {
      r.P = exact_option(o, "kou-p", n, n, true);
    } else {
      const Mat Pn = best.P / Eigen::SelfAdjointEigenSolver<Mat>(best.P).eigenvalues()(
                                  static_cast<Idx>(n) - 1);
      r.P = exact_matrix((Pn + Pn.transpose()) / 2, 1e6);
      for (unsigned i = 0; i < n; ++i)
        for (unsigned j = 0; j < i; ++j) r.P(i, j) = r.P(j, i);
      // Ill-conditioned P: rounding to 1e-6 may lose definiteness; keep the doubles exactly.
      if (Eigen::SelfAdjointEigenSolver<Mat>(to_eigen(r.P)).eigenvalues()(0) <= 0)
        for (unsigned i = 0; i < n; ++i)
          for (unsigned j = 0; j < n; ++j) r.P(i, j) = exact_of_double((Pn(i, j) + Pn(j, i)) / 2);
    }
    const Eigen::VectorXd ep = Eigen::SelfAdjointEigenSolver<Mat>(to_eigen(r.P)).eigenvalues();
    r.sigma_min_P = ep(0);
    r.sigma_max_P = ep(ep.size() - 1);
    if (!(r.sigma_min_P > 0)) {
      r.not_applicable = "the rounded P is not positive definite";
      return r;
    }
    // Sampled verdict on a denser set, then the enclosure.
    const auto report_points = box_samples(ranges, kReportSamples);
    const Jacobians dense = evaluate(m, r.box, report_points);
    const Mat Ld = to_eigen(r.L), Pd = to_eigen(r.P);
    std::size_t worst = 0;
    r.sampled_max_eig = score(dense, Ld, Pd, &worst) * r.sigma_max_P;
    r.sampled_worst = report_points[worst];
    const GiNaC::matrix S = symmetric_part(m, r.L, r.P);
    r.verdict = certify::negative_definite(S, r.box);
    if (r.verdict.kind == certify::BoundKind::sampled && r.sampled_max_eig < 0) {
      certify::EnclosureBudget big;
      big.max_boxes = 1u << 15;
      r.verdict = certify::negative_definite(S, r.box, big);
    }
    r.holds = r.verdict.holds;
    r.rigorous = r.verdict.kind == certify::BoundKind::rigorous;
    if (r.holds || (r.user_L && r.user_P) || round + 1 >= kCertifyRounds ||
        r.tried > kCertifyEvaluations)
      break;
    if (r.verdict.worst_point.size() == r.box.vars.size())
      search_points.push_back(r.verdict.worst_point);
    if (r.sampled_max_eig >= 0) search_points.push_back(r.sampled_worst);
    jac = evaluate(m, r.box, search_points);
    best.score = score(jac, best.L, best.P);
    r.rounds = round + 2;
  }
  return r;
}

std::string options_key(const DesignOptions& o) {
  std::string k;
  for (const char* name : {"kou-gain", "kou-p"})
    if (const std::string* v = o.find(name)) k += std::string(name) + "=" + *v + ";";
  return k;
}

const Result& cached_design(const Model& m, const DesignOptions& o) {
  static std::map<std::string, Result> cache;
  const std::string key = design_cache_key(m) + "#" + options_key(o);
  auto it = cache.find(key);
  if (it == cache.end()) it = cache.emplace(key, design(m, o)).first;
  return it->second;
}

std::vector<std::string> verdict_reasons(const Result& r) {
  if (!r.not_applicable.empty()) return {r.not_applicable};
  const std::string what =
      fmt::format("sym(P (dF/dx + L dh/dx)) with L = {}, P = {} ({}; {} candidates)",
                  matrix_text(r.L), matrix_text(to_eigen(r.P)), r.origin, r.tried);
  const std::string worst = point_text(r.box, r.verdict.worst_point);
  std::vector<std::string> out;
  if (r.holds && r.rigorous)
    out.push_back(fmt::format(
        "{} is negative definite on the whole domain (rigorous: {}): largest eigenvalue <= {:.6g}, "
        "worst box near {}; |e| decays at least at rate {:.6g} (sampled largest eigenvalue "
        "{:.6g})",
        what, r.verdict.method, r.verdict.max_eigenvalue_bound, worst, r.rate(),
        r.sampled_max_eig));
  else if (r.holds)
    out.push_back(fmt::format(
        "{} is negative at every sample (largest sampled eigenvalue {:.6g} near {}) but the "
        "enclosure did not prove it ({}): sampled, not proven",
        what, r.verdict.max_eigenvalue_bound, worst, r.verdict.method));
  else if (r.rigorous)
    out.push_back(fmt::format(
        "condition (9) provably fails on the domain for {}: a direction with v' S v >= 0 at {} "
        "({}); largest sampled eigenvalue {:.6g} at {}",
        what, worst, r.verdict.method, r.sampled_max_eig, point_text(r.box, r.sampled_worst)));
  else
    out.push_back(fmt::format(
        "condition (9) fails on the samples for the best {}: largest sampled eigenvalue {:.6g} "
        "at {} ({})",
        what, r.sampled_max_eig, point_text(r.box, r.sampled_worst), r.verdict.method));
  return out;
}

Verdict applies(const Analysis& a) {
  const Result& r = cached_design(a.model, DesignOptions{});
  Verdict v;
  v.reasons = verdict_reasons(r);
  v.applies = r.not_applicable.empty() && r.holds && r.rigorous;
  return v;
}

std::vector<numeric> flat(const GiNaC::matrix& M) {
  std::vector<numeric> v;
  for (unsigned i = 0; i < M.rows(); ++i)
    for (unsigned j = 0; j < M.cols(); ++j) v.push_back(GiNaC::ex_to<numeric>(M(i, j)));
  return v;
}

ObserverSpec build(const Analysis& a, const DesignOptions& o) {
  const Model& m = a.model;
  const Result& r = cached_design(m, o);
  if (!r.not_applicable.empty() || !r.holds)
    throw UserError(
        SourceLoc{m.file, 0, 0},
        "method 'kou' does not apply: " + fmt::format("{}", fmt::join(verdict_reasons(r), "; ")));
  const std::size_t n = m.n(), p = m.p();
  std::vector<GiNaC::symbol> y;
  for (std::size_t i = 0; i < p; ++i)
    y.push_back(GiNaC::symbol(p == 1 ? std::string("y") : fmt::format("y{}", i + 1)));
  const ExVec F = m.field();
  ExVec rhs;
  for (std::size_t i = 0; i < n; ++i) {
    ex acc = F[i];
    for (std::size_t k = 0; k < p; ++k) acc += r.L(i, k) * (m.h[k] - y[k]);
    rhs.push_back(acc);
  }
  ObserverSpec s;
  s.method = "kou";
  s.class_suffix = "Kou";
  s.state_size = n;
  s.params = runtime_params(m);
  s.functions = model_functions(m);
  GeneratedFunction f;
  f.name = "x_rhs";
  f.doc = "xh' = f(xh) + g(xh, u) + L (h(xh) - y)  (seed 001 eq. 5).";
  f.args = {state_arg(m), input_arg(m), output_arg(y)};
  f.outputs = rhs;
  f.out_rows = n;
  f.out_type = "State";
  s.functions.push_back(f);
  s.state_name = "xh";
  s.state_doc = "the estimate itself";
  s.update = UpdateKind::ode;
  s.roles.rhs = "x_rhs";
  const char* kind = r.rigorous ? "rigorous" : "sampled, not proven";
  s.title = "Kou-Elliott-Tarn observer (uniformly negative definite P (df/dx + L dh/dx))";
  s.description = {
      "Observer: Kou-Elliott-Tarn (1975; seed 001 §4, Theorem 1, eq. 5-9)",
      fmt::format("L = {}, P = {}", matrix_text(r.L), matrix_text(to_eigen(r.P))),
      fmt::format(
          "Certificate (9): largest eigenvalue of sym(P (dF/dx + L dh/dx)) <= {:.6g} on the "
          "domain ({})",
          r.verdict.max_eigenvalue_bound, kind)};
  s.class_doc = {
      "  xh' = f(xh) + g(xh, u) + L (h(xh) - y)   (seed 001 eq. 5, L (yh - y))",
      fmt::format("V = e' P e decays while x and xh stay in the domain box: |e| rate >= {:.4g}.",
                  r.rate())};
  s.constants.push_back({"L", flat(r.L), "output-injection gain, n x p row-major"});
  s.constants.push_back({"P", flat(r.P), "Lyapunov matrix of eq. (9), row-major"});
  s.report = {
      {"convention", "xh' = f + g + L (h(xh) - y) (seed eq. 5), e = xh - x"},
      {"L",
       fmt::format("{} ({})", matrix_text(r.L), r.user_L ? "given with --kou-gain" : "searched")},
      {"P",
       fmt::format("{} ({}); sigma(P) in [{:.6g}, {:.6g}]", matrix_text(to_eigen(r.P)),
                   r.user_P ? "given with --kou-p" : "searched", r.sigma_min_P, r.sigma_max_P)},
      {"search", fmt::format("{}; {} candidates evaluated on {} samples plus the enclosure's "
                             "counterexamples; {} search-and-certify round(s)",
                             r.origin, r.tried, kSearchSamples, r.rounds)},
      {"largest eigenvalue bound",
       fmt::format("{:.6g} ({}: {}), worst box near {}", r.verdict.max_eigenvalue_bound,
                   certify::bound_kind_name(r.verdict.kind), r.verdict.method,
                   point_text(r.box, r.verdict.worst_point))},
      {"sampled largest eigenvalue",
       fmt::format("{:.6g} at {} ({} samples)", r.sampled_max_eig,
                   point_text(r.box, r.sampled_worst), kReportSamples)},
      {"decay rate",
       fmt::format("|e(t)| <= sqrt({:.6g}) |e(0)| exp(-{:.6g} t) while x, xh stay in the domain",
                   r.sigma_max_P / r.sigma_min_P, r.rate())}};
  s.summary = fmt::format(
      "Kou-Elliott-Tarn observer, L = {}, certificate: largest eigenvalue of sym(P (dF/dx + L "
      "dh/dx)) "
      "<= {:.6g} on the domain ({})",
      matrix_text(r.L), r.verdict.max_eigenvalue_bound, kind);
  return s;
}

}  // namespace

KouCertificate kou_certificate(const Model& m, const DesignOptions& o) {
  const Result& r = cached_design(m, o);
  KouCertificate c;
  c.not_applicable = r.not_applicable;
  if (!c.not_applicable.empty()) return c;
  for (const auto& v : flat(r.L)) c.L.push_back(v.to_double());
  for (const auto& v : flat(r.P)) c.P.push_back(v.to_double());
  c.holds = r.holds;
  c.rigorous = r.rigorous;
  c.max_eigenvalue_bound = r.verdict.max_eigenvalue_bound;
  c.sampled_max_eigenvalue = r.sampled_max_eig;
  c.worst_point = r.verdict.worst_point;
  c.sigma_min_P = r.sigma_min_P;
  c.sigma_max_P = r.sigma_max_P;
  return c;
}

Design kou_design() {
  Design d;
  d.name = "kou";
  d.summary =
      "Kou-Elliott-Tarn observer: P (df/dx + L dh/dx) < 0 on the domain (seed 001 Theorem 1)";
  d.options = {{"kou-gain", "Kou observer: gain L, n*p entries row-major", "searched"},
               {"kou-p", "Kou observer: P, n diagonal entries or n*n row-major", "searched"}};
  d.applies = applies;
  d.build = build;
  d.verdict_searches = true;  // a search over gains with Arb bounds: seconds
  return d;
}

}  // namespace obsynth
