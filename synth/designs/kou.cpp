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
#include "front/fresh_names.hpp"
#include "symbolic/dag.hpp"
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
// Past kExhaustiveStates states the search takes its budgeted form (models with n <= 4, the
// bundled ones among them, keep the exhaustive one and their outputs): Nelder-Mead scores a
// candidate on an active subset of the samples (the kActive worst for the starting candidate,
// then the worst of each result joins, at most kActiveRounds times per phase); each
// candidate kept is still scored on all samples. Each Nelder-Mead run stops after
// kSolveBudget / |active| evaluations, and the enclosure is capped at kWorkBudget ball
// operations and its second try at 2^14 boxes (deterministic budgets); when it cannot decide,
// the verdict is "sampled" (not proven), never certified.
constexpr std::size_t kExhaustiveStates = 4;
constexpr std::size_t kActive = 24;
constexpr int kActiveRounds = 3;
constexpr std::size_t kSolveBudget = 60000;
constexpr std::size_t kWorkBudget = std::size_t{1} << 24;

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
// With `subset`, k runs over those sample indices only.
double score(const Jacobians& jac, const Mat& L, const Mat& P, std::size_t* worst = nullptr,
             const std::vector<std::size_t>* subset = nullptr) {
  const Eigen::VectorXd ep =
      Eigen::SelfAdjointEigenSolver<Mat>(P, Eigen::EigenvaluesOnly).eigenvalues();
  if (!(ep(0) > 0) || !std::isfinite(ep(ep.size() - 1)))
    return std::numeric_limits<double>::infinity();
  double best = -std::numeric_limits<double>::infinity();
  const std::size_t count = subset ? subset->size() : jac.J.size();
  for (std::size_t q = 0; q < count; ++q) {
    const std::size_t k = subset ? (*subset)[q] : q;
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

struct Candidate {
  Mat L, P;
  double score = std::numeric_limits<double>::infinity();
  std::string origin;
};

// The expansion point of the linearisation: the origin in the states and inputs when the box
// holds it, else the box's centre (parameters always at their centre).
std::vector<double> expansion_point(const Model& m, const certify::Box& box) {
  std::vector<double> star;
  for (std::size_t k = 0; k < box.vars.size(); ++k) {
    const auto& rg = box.ranges[k];
    bool is_param = true;
    for (const auto& x : m.states) is_param = is_param && !box.vars[k].is_equal(x);
    for (const auto& u : m.inputs) is_param = is_param && !box.vars[k].is_equal(u);
    star.push_back(!is_param && rg.lo <= 0 && 0 <= rg.hi ? 0.0 : (rg.lo + rg.hi) / 2);
  }
  return star;
}

// One search-and-certify run of design(): the user's L and P where given, the Jacobians at
// the search samples and the best candidate so far; the methods are its stages, in order.
class KouSearch {
 public:
  KouSearch(const Model& m, Result& r, std::optional<Mat> uL, std::optional<Mat> uP)
      : m_(m), r_(r), n_(m.n()), p_(m.p()), uL_(std::move(uL)), uP_(std::move(uP)) {
    for (const auto& rg : r_.box.ranges) ranges_.emplace_back(rg.lo, rg.hi);
    points_ = box_samples(ranges_, kSearchSamples);
    jac_ = evaluate(m_, r_.box, points_);
  }
  void seed();
  void refine();
  bool finite() const { return std::isfinite(best_.score); }
  const std::string& best_origin() const { return best_.origin; }
  bool make_exact(const DesignOptions& o);
  void certify_exact(bool last_round);
  void add_counterexamples(int round);

 private:
  void consider(const Mat& L, const Mat& P, const std::string& origin);
  std::optional<Mat> lyapunov_P(const Mat& L, const Mat& A0, const Mat& C0) const;
  std::vector<Mat> gain_candidates(const Mat& A0, const Mat& C0) const;
  std::vector<double> pack(const Candidate& c) const;
  void unpack(const std::vector<double>& w, std::size_t nl, Mat& L, Mat& P) const;
  Candidate nelder_mead_from(
      const std::vector<double>& from, std::size_t nl, double scale,
      const std::function<double(const Mat&, const Mat&, double)>& objective);
  Candidate budgeted_nelder_mead_from(
      const Candidate& start, std::size_t nl, double scale,
      const std::function<double(const Mat&, const Mat&, double)>& objective);
  std::vector<std::size_t> worst_samples(const Mat& L, const Mat& P, std::size_t count) const;

  const Model& m_;
  Result& r_;
  const std::size_t n_, p_;
  const std::optional<Mat> uL_, uP_;
  std::vector<std::pair<double, double>> ranges_;
  std::vector<std::vector<double>> points_;  // the search samples and counterexamples
  Jacobians jac_;
  Candidate best_;
  const bool budgeted_ = n_ > kExhaustiveStates;
  std::vector<std::size_t> active_;  // budgeted: the samples Nelder-Mead scores on
};

void KouSearch::consider(const Mat& L, const Mat& P, const std::string& origin) {
  ++r_.tried;
  const double s = score(jac_, L, P);
  if (s < best_.score) best_ = {L, P, s, origin};
}

// P solving the linearisation's Lyapunov equation for L, normalised to sigma_max(P) = 1.
std::optional<Mat> KouSearch::lyapunov_P(const Mat& L, const Mat& A0, const Mat& C0) const {
  const auto P =
      solve_lyapunov(A0 + L * C0, Mat::Identity(static_cast<Idx>(n_), static_cast<Idx>(n_)));
  if (!P || Eigen::SelfAdjointEigenSolver<Mat>(*P).eigenvalues()(0) <= 0) return std::nullopt;
  return Mat(*P / Eigen::SelfAdjointEigenSolver<Mat>(*P).eigenvalues()(static_cast<Idx>(n_) - 1));
}

// The given L, or L = 0 and one pole placement per output and pole set of the linearisation.
std::vector<Mat> KouSearch::gain_candidates(const Mat& A0, const Mat& C0) const {
  std::vector<Mat> out;
  if (uL_) return {*uL_};
  out.push_back(Mat::Zero(static_cast<Idx>(n_), static_cast<Idx>(p_)));
  for (std::size_t i = 0; i < p_; ++i)
    for (const auto& poles : candidate_pole_sets(n_)) {
      if (-*std::min_element(poles.begin(), poles.end()) > kMaxPole) continue;
      const auto l = place_poles(A0, C0.row(static_cast<Idx>(i)), poles);
      if (!l) continue;
      Mat L = Mat::Zero(static_cast<Idx>(n_), static_cast<Idx>(p_));
      L.col(static_cast<Idx>(i)) = *l;
      out.push_back(L);
    }
  return out;
}

// The first candidates, from the linearisation at the expansion point: each L with the given
// P, or with P = I and the Lyapunov P.
void KouSearch::seed() {
  const Jacobians lin = evaluate(m_, r_.box, {expansion_point(m_, r_.box)});
  const Mat& A0 = lin.J[0];
  const Mat& C0 = lin.H[0];
  const Mat I = Mat::Identity(static_cast<Idx>(n_), static_cast<Idx>(n_));
  for (const auto& L : gain_candidates(A0, C0)) {
    if (uP_) {
      consider(L, *uP_, "");
      continue;
    }
    consider(L, I, "P = I");
    if (const auto P = lyapunov_P(L, A0, C0))
      consider(L, *P, "P from the Lyapunov equation of the linearisation");
  }
}

// The free entries Nelder-Mead varies: L row-major unless given, then P's Cholesky factor
// unless given.
std::vector<double> KouSearch::pack(const Candidate& c) const {
  std::vector<double> w;
  if (!uL_)
    for (Idx i = 0; i < c.L.rows(); ++i)
      for (Idx j = 0; j < c.L.cols(); ++j) w.push_back(c.L(i, j));
  if (!uP_) push_factor(c.P, w);
  return w;
}

// The inverse of pack; nl is the number of L entries in w.
void KouSearch::unpack(const std::vector<double>& w, std::size_t nl, Mat& L, Mat& P) const {
  L = uL_ ? *uL_ : Mat(static_cast<Idx>(n_), static_cast<Idx>(p_));
  if (!uL_)
    for (std::size_t k = 0; k < nl; ++k)
      L(static_cast<Idx>(k / p_), static_cast<Idx>(k % p_)) = w[k];
  P = uP_ ? *uP_ : P_of(w, n_, nl);
}

Candidate KouSearch::nelder_mead_from(
    const std::vector<double>& from, std::size_t nl, double scale,
    const std::function<double(const Mat&, const Mat&, double)>& objective) {
  const std::vector<std::size_t>* subset = budgeted_ ? &active_ : nullptr;
  int evals = 200 * static_cast<int>(from.size() + 1);
  if (budgeted_)
    evals =
        std::min(evals, static_cast<int>(kSolveBudget / std::max<std::size_t>(1, active_.size())));
  const auto w = nelder_mead(
      [&](const std::vector<double>& w) {
        ++r_.tried;
        Mat L, P;
        unpack(w, nl, L, P);
        return objective(L, P, score(jac_, L, P, nullptr, subset));
      },
      from, 0.1 * scale, evals);
  Candidate c;
  unpack(w, nl, c.L, c.P);
  c.score = score(jac_, c.L, c.P);
  return c;
}

// The `count` samples with the largest eigenvalue for L, P (largest first).
std::vector<std::size_t> KouSearch::worst_samples(const Mat& L, const Mat& P,
                                                  std::size_t count) const {
  std::vector<std::pair<double, std::size_t>> v;
  for (std::size_t k = 0; k < jac_.J.size(); ++k) {
    const Mat N = P * (jac_.J[k] + L * jac_.H[k]);
    const double e = lambda_max((N + N.transpose()) / 2);
    v.emplace_back(std::isfinite(e) ? e : std::numeric_limits<double>::infinity(), k);
  }
  std::stable_sort(v.begin(), v.end(),
                   [](const auto& a, const auto& b) { return a.first > b.first; });
  std::vector<std::size_t> out;
  for (std::size_t i = 0; i < v.size() && i < count; ++i) out.push_back(v[i].second);
  return out;
}

// Nelder-Mead on the active samples (budgeted form): the start's worst kActive samples join
// the active set, and after each run the result's worst few (on all samples) join it and the
// run resumes from the result, until the result's worst sample is already active.
Candidate KouSearch::budgeted_nelder_mead_from(
    const Candidate& start, std::size_t nl, double scale,
    const std::function<double(const Mat&, const Mat&, double)>& objective) {
  auto join = [&](const std::vector<std::size_t>& idx) {
    bool added = false;
    for (std::size_t k : idx)
      if (std::find(active_.begin(), active_.end(), k) == active_.end()) {
        active_.push_back(k);
        added = true;
      }
    return added;
  };
  join(worst_samples(start.L, start.P, kActive));
  Candidate c = start;
  for (int round = 0; round < kActiveRounds; ++round) {
    c = nelder_mead_from(pack(c), nl, scale, objective);
    if (!join(worst_samples(c.L, c.P, 4))) break;
  }
  return c;
}

// Nelder-Mead on the free entries, in two phases; the score is capped at the decay rate
// kRateCap, past which higher gains buy rate the certificate does not need.
void KouSearch::refine() {
  const std::vector<double> v = pack(best_);
  const std::size_t nl = uL_ ? 0 : static_cast<std::size_t>(best_.L.size());
  double scale = 1;
  for (double x : v) scale = std::max(scale, std::fabs(x));
  // Phase 1: the most negative sampled eigenvalue (per sigma_max(P)), capped at kRateCap.
  const auto phase1 = [](const Mat& L, const Mat&, double s) {
    return std::max(s, -kRateCap) + 1e-6 * L.squaredNorm();
  };
  Candidate c1 = budgeted_ ? budgeted_nelder_mead_from(best_, nl, scale, phase1)
                           : nelder_mead_from(v, nl, scale, phase1);
  if (std::max(c1.score, -kRateCap) < std::max(best_.score, -kRateCap)) {
    c1.origin = best_.origin;
    if (c1.origin.find("refined") == std::string::npos)
      c1.origin += std::string(c1.origin.empty() ? "" : ", ") + "refined by Nelder-Mead on samples";
    best_ = c1;
  }
  // Phase 2, once certified on the samples: smaller gains, keeping at least half that rate
  // (budgeted: three quarters, a margin that lets the capped enclosure prove it; an 8-state
  // chain with a sine in every equation was left undecided with half).
  if (best_.score < 0 && !uL_) {
    const double keep = budgeted_ ? best_.score * 3 / 4 : best_.score / 2;
    const auto phase2 = [&](const Mat& L, const Mat&, double s) {
      return s > keep ? std::numeric_limits<double>::infinity() : L.squaredNorm();
    };
    Candidate c2 = budgeted_ ? budgeted_nelder_mead_from(best_, nl, scale, phase2)
                             : nelder_mead_from(pack(best_), nl, scale, phase2);
    if (c2.score <= keep && c2.L.squaredNorm() < best_.L.squaredNorm()) {
      c2.origin = best_.origin;
      if (c2.origin.find("gains reduced") == std::string::npos)
        c2.origin += std::string(c2.origin.empty() ? "" : ", ") +
                     (budgeted_ ? "gains reduced keeping three quarters of the sampled rate"
                                : "gains reduced keeping half the sampled rate");
      best_ = c2;
    }
  }
}

// Exact L and P: as given, or rounded (L to 1e-3, P normalised to sigma_max 1, to 1e-6).
// False (r.not_applicable set) when the rounded P is not positive definite.
bool KouSearch::make_exact(const DesignOptions& o) {
  r_.L = uL_ ? exact_option(o, "kou-gain", n_, p_, false) : exact_matrix(best_.L, 1e3);
  if (uP_) {
    r_.P = exact_option(o, "kou-p", n_, n_, true);
  } else {
    const Mat Pn = best_.P / Eigen::SelfAdjointEigenSolver<Mat>(best_.P).eigenvalues()(
                                 static_cast<Idx>(n_) - 1);
    r_.P = exact_matrix((Pn + Pn.transpose()) / 2, 1e6);
    for (unsigned i = 0; i < n_; ++i)
      for (unsigned j = 0; j < i; ++j) r_.P(i, j) = r_.P(j, i);
    // Ill-conditioned P: rounding to 1e-6 may lose definiteness; keep the doubles exactly.
    if (Eigen::SelfAdjointEigenSolver<Mat>(to_eigen(r_.P)).eigenvalues()(0) <= 0)
      for (unsigned i = 0; i < n_; ++i)
        for (unsigned j = 0; j < n_; ++j) r_.P(i, j) = exact_of_double((Pn(i, j) + Pn(j, i)) / 2);
  }
  const Eigen::VectorXd ep = Eigen::SelfAdjointEigenSolver<Mat>(to_eigen(r_.P)).eigenvalues();
  r_.sigma_min_P = ep(0);
  r_.sigma_max_P = ep(ep.size() - 1);
  if (!(r_.sigma_min_P > 0)) {
    r_.not_applicable = "the rounded P is not positive definite";
    return false;
  }
  return true;
}

// The sampled verdict on a denser set, then the enclosure (with a bigger budget when the
// samples say it holds but the first enclosure could not prove it). Budgeted form: when a
// sample already refutes the candidate, the enclosure runs only in the last round, to prove
// the failure (a smaller budget: it needs one point, not a tight bound).
void KouSearch::certify_exact(bool last_round) {
  const auto report_points = box_samples(ranges_, kReportSamples);
  const Jacobians dense = evaluate(m_, r_.box, report_points);
  const Mat Ld = to_eigen(r_.L), Pd = to_eigen(r_.P);
  std::size_t worst = 0;
  r_.sampled_max_eig = score(dense, Ld, Pd, &worst) * r_.sigma_max_P;
  r_.sampled_worst = report_points[worst];
  if (budgeted_ && r_.sampled_max_eig >= 0 && !last_round) {
    r_.verdict = certify::DefinitenessVerdict{};
    r_.verdict.kind = certify::BoundKind::sampled;
    r_.verdict.max_eigenvalue_bound = r_.sampled_max_eig;
    r_.verdict.worst_point = r_.sampled_worst;
    r_.verdict.method = "sampled: fails at a sample (no enclosure before the last round)";
    r_.holds = false;
    r_.rigorous = false;
    return;
  }
  const GiNaC::matrix S = symmetric_part(m_, r_.L, r_.P);
  certify::EnclosureBudget first;
  if (budgeted_) first.max_work = r_.sampled_max_eig >= 0 ? kWorkBudget / 8 : kWorkBudget;
  r_.verdict = certify::negative_definite(S, r_.box, first);
  if (r_.verdict.kind == certify::BoundKind::sampled && r_.sampled_max_eig < 0) {
    certify::EnclosureBudget big;
    big.max_boxes = budgeted_ ? 1u << 14 : 1u << 15;
    if (budgeted_) big.max_work = 4 * kWorkBudget;
    r_.verdict = certify::negative_definite(S, r_.box, big);
  }
  r_.holds = r_.verdict.holds;
  r_.rigorous = r_.verdict.kind == certify::BoundKind::rigorous;
}

// The enclosure's and the samples' worst points join the search samples; the best candidate
// is scored again on them for the next round.
void KouSearch::add_counterexamples(int round) {
  if (r_.verdict.worst_point.size() == r_.box.vars.size())
    points_.push_back(r_.verdict.worst_point);
  if (r_.sampled_max_eig >= 0) points_.push_back(r_.sampled_worst);
  jac_ = evaluate(m_, r_.box, points_);
  best_.score = score(jac_, best_.L, best_.P);
  r_.rounds = round + 2;
}

// --kou-gain and --kou-p, P checked symmetric positive definite.
std::pair<std::optional<Mat>, std::optional<Mat>> user_matrices(const DesignOptions& o,
                                                                std::size_t n, std::size_t p) {
  auto uL = matrix_option(o, "kou-gain", n, p, false);
  auto uP = matrix_option(o, "kou-p", n, n, true);
  if (uP) {
    if (!uP->isApprox(uP->transpose(), 0))
      throw UserError(SourceLoc{}, "--kou-p: P must be symmetric");
    if (Eigen::SelfAdjointEigenSolver<Mat>(*uP).eigenvalues()(0) <= 0)
      throw UserError(SourceLoc{}, "--kou-p: P must be positive definite");
  }
  return {std::move(uL), std::move(uP)};
}

Result design(const Model& m, const DesignOptions& o) {
  Result r;
  const std::size_t n = m.n(), p = m.p();
  r.n = n;
  r.p = p;
  r.box = certify::model_box(m);
  auto [uL, uP] = user_matrices(o, n, p);
  r.user_L = uL.has_value();
  r.user_P = uP.has_value();
  KouSearch search(m, r, std::move(uL), std::move(uP));
  search.seed();
  const bool both_given = r.user_L && r.user_P;
  r.origin = both_given ? "L and P given" : search.best_origin();
  // Search and certify; when the enclosure refutes the candidate, its worst point joins the
  // samples and the search resumes from the candidate (up to kCertifyRounds rounds).
  for (int round = 0;; ++round) {
    if (!both_given && search.finite()) {
      search.refine();
      r.origin = search.best_origin();
    }
    if (!search.finite()) {
      r.not_applicable = "no L, P candidate could be evaluated on the domain samples";
      return r;
    }
    if (r.origin.empty()) r.origin = r.user_L ? "L given, P searched" : "P given, L searched";
    if (!search.make_exact(o)) return r;
    const bool last = both_given || round + 1 >= kCertifyRounds || r.tried > kCertifyEvaluations;
    search.certify_exact(last);
    if (r.holds || last) break;
    search.add_counterexamples(round);
  }
  return r;
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

Verdict verdict_of(const Analysis&, const Lazy<Result>& work) {
  const Result& r = work.get();
  Verdict v;
  v.reasons = verdict_reasons(r);
  v.applies = r.not_applicable.empty() && r.holds;
  if (v.applies && r.rigorous) {
    v.guarantee = Guarantee::rigorous;
    v.guarantee_text = fmt::format(
        "condition (9) proved over the whole domain box (Arb): |e| decays at rate {:.3g} or "
        "faster",
        r.rate());
  } else if (v.applies) {  // negative at every sample, the enclosure undecided
    v.guarantee = Guarantee::partial;
    v.guarantee_text = fmt::format(
        "sampled, not a proof: condition (9) holds at every sample (largest sampled eigenvalue "
        "{:.6g}) but the Arb enclosure did not prove it ({}); where it holds |e| decays at rate "
        "{:.3g} or faster",
        r.verdict.max_eigenvalue_bound, r.verdict.method, r.rate());
  }
  return v;
}

std::vector<numeric> flat(const GiNaC::matrix& M) {
  std::vector<numeric> v;
  for (unsigned i = 0; i < M.rows(); ++i)
    for (unsigned j = 0; j < M.cols(); ++j) v.push_back(GiNaC::ex_to<numeric>(M(i, j)));
  return v;
}

// The spec without its texts: the estimate is the state, integrated by
// xh' = f(xh) + g(xh, u) + L (h(xh) - y)  (seed 001 eq. 5).
ObserverSpec kou_skeleton(const Model& m, const GiNaC::matrix& L) {
  const std::size_t n = m.n(), p = m.p();
  const std::vector<GiNaC::symbol> y = measurement_symbols(m);
  const ExVec F = m.field();
  ExVec rhs;
  for (std::size_t i = 0; i < n; ++i) {
    ex acc = F[i];
    for (std::size_t k = 0; k < p; ++k) acc += L(i, k) * (m.h[k] - y[k]);
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
  return s;
}

// The report rows: L, P, how they were found, and the certificate's numbers.
std::vector<ReportRow> kou_report(const Result& r) {
  return {
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
}

ObserverSpec build_from(const Analysis& a, const Result& r) {
  const Model& m = a.model;
  if (!r.not_applicable.empty() || !r.holds)
    throw UserError(
        SourceLoc{m.file, 0, 0},
        "method 'kou' does not apply: " + fmt::format("{}", fmt::join(verdict_reasons(r), "; ")));
  ObserverSpec s = kou_skeleton(m, r.L);
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
  s.report = kou_report(r);
  s.summary = fmt::format(
      "Kou-Elliott-Tarn observer, L = {}, certificate: largest eigenvalue of sym(P (dF/dx + L "
      "dh/dx)) "
      "<= {:.6g} on the domain ({})",
      matrix_text(r.L), r.verdict.max_eigenvalue_bound, kind);
  return s;
}

}  // namespace

KouCertificate kou_certificate(const Model& m, const DesignOptions& o) {
  const Result r = design(m, o);
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
  d.plan = work_plan<Result, design, verdict_of, build_from>;
  d.verdict_searches = true;     // a search over gains with Arb bounds: seconds
  d.accepts_feedthrough = true;  // L (h(xh, u) - y), condition (9) over the input box too
  return d;
}

}  // namespace obsynth
