#include "certify/enclosure.hpp"

#include <arb_mat.h>
#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <queue>

#include "certify/sampling.hpp"
#include "certify/tape.hpp"

namespace obsynth::certify {

using detail::BallVec;
using detail::kPrec;
using detail::Tape;
using GiNaC::ex;

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

}  // namespace

// ----- deterministic sample points -------------------------------------------------------

std::vector<std::vector<double>> sample_points(const Box& box, std::size_t n) {
  static const unsigned primes[] = {2,  3,  5,  7,  11, 13, 17, 19, 23, 29, 31, 37, 41,
                                    43, 47, 53, 59, 61, 67, 71, 73, 79, 83, 89, 97};
  const std::size_t d = box.vars.size();
  std::vector<std::vector<double>> pts;
  std::vector<double> c(d);
  for (std::size_t k = 0; k < d; ++k) c[k] = 0.5 * (box.ranges[k].lo + box.ranges[k].hi);
  pts.push_back(c);
  if (d <= 12) {
    for (std::size_t mask = 0; mask < (std::size_t{1} << d) && pts.size() < n; ++mask) {
      std::vector<double> p(d);
      for (std::size_t k = 0; k < d; ++k)
        p[k] = (mask >> k) & 1 ? box.ranges[k].hi : box.ranges[k].lo;
      pts.push_back(p);
    }
  }
  for (std::size_t i = 1; pts.size() < n; ++i) {
    std::vector<double> p(d);
    for (std::size_t k = 0; k < d; ++k) {
      const double t = radical_inverse(i + 7 * (k / 25), primes[k % 25]);
      p[k] = box.ranges[k].lo + t * (box.ranges[k].hi - box.ranges[k].lo);
    }
    pts.push_back(p);
  }
  return pts;
}

namespace {

// ----- point values: the tape in doubles, or GiNaC when the tape cannot evaluate ---------

class PointEval {
 public:
  PointEval(const std::vector<ex>& outs, const Box& box, const Tape& tape)
      : outs_(outs), box_(box), tape_(tape) {}
  std::vector<double> operator()(const std::vector<double>& x) const {
    std::vector<double> out;
    if (tape_.supported()) {
      tape_.eval_double(x, out);
      return out;
    }
    GiNaC::exmap sub;
    for (std::size_t k = 0; k < box_.vars.size(); ++k) sub[box_.vars[k]] = GiNaC::numeric(x[k]);
    for (const auto& e : outs_) {
      double v = std::nan("");
      try {
        const ex r = GiNaC::evalf(e.subs(sub));
        if (GiNaC::is_a<GiNaC::numeric>(r) && GiNaC::ex_to<GiNaC::numeric>(r).is_real())
          v = GiNaC::ex_to<GiNaC::numeric>(r).to_double();
      } catch (const std::exception&) {
      }
      out.push_back(v);
    }
    return out;
  }

 private:
  const std::vector<ex>& outs_;
  const Box& box_;
  const Tape& tape_;
};

// ----- enclosures of several outputs over a box: natural interval extension intersected with
// the mean-value form f(c) + grad f(X) (X - c) (second-order tight on small boxes) ------------

class BoxEnclosure {
 public:
  BoxEnclosure(const std::vector<ex>& outs, const Box& box)
      : m_(outs.size()), tape_(outs, box.vars) {
    if (!tape_.supported()) return;
    const std::vector<bool> used = tape_.used_vars();
    for (std::size_t k = 0; k < used.size(); ++k)
      if (used[k] && box.ranges[k].hi > box.ranges[k].lo) dvars_.push_back(k);
    if (dvars_.empty()) return;
    // Gradients symbolically; skipped for abs (not differentiable) and for huge tapes.
    std::vector<ex> all = outs;
    for (const auto& e : outs) {
      if (e.has(GiNaC::abs(GiNaC::wild()))) return;
      for (std::size_t k : dvars_) all.push_back(e.diff(box.vars[k]));
    }
    auto mv = std::make_unique<Tape>(all, box.vars);
    if (!mv->supported() || mv->size() > 20 * tape_.size() + 2000) return;
    mv_ = std::move(mv);
    full_ = BallVec(all.size());
    centre_ = BallVec(outs.size());
  }

  const Tape& tape() const { return tape_; }
  bool supported() const { return tape_.supported(); }
  const std::string& why() const { return tape_.why(); }
  std::vector<bool> used_vars() const { return tape_.used_vars(); }

  // Enclosures of the outputs over [lo, hi]; false when Arb cannot bound them there.
  bool eval(const std::vector<double>& lo, const std::vector<double>& hi, BallVec& out) {
    if (out.size() != m_) out = BallVec(m_);
    if (!mv_) return tape_.eval_box(lo, hi, out);
    // A gradient that Arb cannot bound (sqrt at 0) leaves the natural extension alone.
    if (!mv_->eval_box(lo, hi, full_)) return tape_.eval_box(lo, hi, out);
    for (std::size_t i = 0; i < m_; ++i) arb_set(out[i], full_[i]);
    if (mv_->clamped()) return true;
    std::vector<double> c(lo.size());
    for (std::size_t k = 0; k < lo.size(); ++k) c[k] = 0.5 * (lo[k] + hi[k]);
    if (!tape_.eval_point(c, centre_) || tape_.clamped()) return true;
    const std::size_t nd = dvars_.size();
    arb_t dx, t, e;
    arb_init(dx);
    arb_init(t);
    arb_init(e);
    arf_t a, b, cc;
    arf_init(a);
    arf_init(b);
    arf_init(cc);
    for (std::size_t i = 0; i < m_; ++i) {
      arb_set(e, centre_[i]);
      for (std::size_t j = 0; j < nd; ++j) {
        const std::size_t k = dvars_[j];
        // X_k - c_k, rounded outward.
        arf_set_d(a, lo[k]);
        arf_set_d(b, hi[k]);
        arf_set_d(cc, c[k]);
        arf_sub(a, a, cc, kPrec, ARF_RND_FLOOR);
        arf_sub(b, b, cc, kPrec, ARF_RND_CEIL);
        arb_set_interval_arf(dx, a, b, kPrec);
        arb_mul(t, full_[m_ + i * nd + j], dx, kPrec);
        arb_add(e, e, t, kPrec);
      }
      if (arb_is_finite(e) && arb_overlaps(e, out[i])) arb_intersection(out[i], out[i], e, kPrec);
    }
    arf_clear(a);
    arf_clear(b);
    arf_clear(cc);
    arb_clear(dx);
    arb_clear(t);
    arb_clear(e);
    return true;
  }

  bool eval_point(const std::vector<double>& x, BallVec& out) { return tape_.eval_point(x, out); }

  // Ball operations of one box evaluation (the tapes run by eval, at least 1).
  std::size_t work_per_box() const {
    return std::max<std::size_t>(1, tape_.size() + (mv_ ? mv_->size() + tape_.size() : 0));
  }
  // The budget with max_boxes lowered to what max_work allows (at least 1 box).
  EnclosureBudget capped(const EnclosureBudget& b) const {
    EnclosureBudget c = b;
    if (b.max_work > 0)
      c.max_boxes = std::max<std::size_t>(1, std::min(b.max_boxes, b.max_work / work_per_box()));
    return c;
  }

 private:
  std::size_t m_;
  Tape tape_;
  std::unique_ptr<Tape> mv_;
  std::vector<std::size_t> dvars_;
  BallVec full_, centre_;
};

// ----- branch and bound ------------------------------------------------------------------

struct Objective {
  // Rigorous upper bound over [lo, hi]; +inf when Arb cannot bound it there.
  std::function<double(const std::vector<double>&, const std::vector<double>&)> upper;
  // Value at a point (NaN where undefined).
  std::function<double(const std::vector<double>&)> at;
};

struct BBResult {
  double upper = kInf;
  double best = -kInf;
  std::vector<double> best_point;
  std::size_t boxes = 0;
};

BBResult branch_and_bound(const Box& box, const Objective& obj, const EnclosureBudget& budget,
                          bool use_gap, const std::function<bool(double, double)>& stop,
                          const std::vector<bool>& split_dims) {
  const std::size_t d = box.vars.size();
  BBResult res;
  auto consider = [&](const std::vector<double>& p) {
    const double v = obj.at(p);
    if (!std::isnan(v) && (v > res.best || res.best_point.empty())) {
      res.best = v;
      res.best_point = p;
    }
  };
  for (const auto& p : sample_points(box, 64)) consider(p);

  struct Item {
    double ub;
    std::vector<double> lo, hi;
    bool operator<(const Item& o) const { return ub < o.ub; }
  };
  std::vector<double> lo(d), hi(d), w0(d);
  for (std::size_t k = 0; k < d; ++k) {
    lo[k] = box.ranges[k].lo;
    hi[k] = box.ranges[k].hi;
    w0[k] = split_dims.empty() || split_dims[k] ? hi[k] - lo[k] : 0;  // 0: never split
  }
  std::priority_queue<Item> heap;
  heap.push({obj.upper(lo, hi), lo, hi});
  res.boxes = 1;
  double finals = -kInf;
  while (!heap.empty() && res.boxes < budget.max_boxes) {
    const Item& top = heap.top();
    if (stop && stop(top.ub, res.best)) break;
    if (use_gap && std::isfinite(top.ub) &&
        top.ub - res.best <= std::max(budget.relative_gap * std::fabs(res.best), 1e-12))
      break;
    Item it = top;
    heap.pop();
    std::size_t k = d;
    double best_ratio = 0;
    for (std::size_t j = 0; j < d; ++j) {
      if (w0[j] <= 0) continue;
      const double ratio = (it.hi[j] - it.lo[j]) / w0[j];
      if (ratio > best_ratio) {
        best_ratio = ratio;
        k = j;
      }
    }
    const double mid = 0.5 * (it.lo[k < d ? k : 0] + it.hi[k < d ? k : 0]);
    if (k == d || best_ratio < 1e-12 || !(mid > it.lo[k] && mid < it.hi[k])) {
      finals = std::max(finals, it.ub);  // cannot split further
      continue;
    }
    Item a{0, it.lo, it.hi}, b{0, it.lo, it.hi};
    a.hi[k] = mid;
    b.lo[k] = mid;
    for (Item* c : {&a, &b}) {
      c->ub = obj.upper(c->lo, c->hi);
      ++res.boxes;
      std::vector<double> centre(d);
      for (std::size_t j = 0; j < d; ++j) centre[j] = 0.5 * (c->lo[j] + c->hi[j]);
      consider(centre);
      heap.push(std::move(*c));
    }
  }
  res.upper = finals;
  if (!heap.empty()) res.upper = std::max(res.upper, heap.top().ub);
  if (std::isnan(res.upper)) res.upper = kInf;
  return res;
}

// ----- rigorous matrix bounds from balls -------------------------------------------------

struct ArbMat {
  ArbMat(slong r, slong c) { arb_mat_init(m, r, c); }
  ~ArbMat() { arb_mat_clear(m); }
  ArbMat(const ArbMat&) = delete;
  ArbMat& operator=(const ArbMat&) = delete;
  arb_mat_t m;
};

// A positive vector for Collatz-Wielandt: power iteration on G, entries floored at 1e-9 of
// the largest and scaled to max 1.
Eigen::VectorXd perron_vector(const Eigen::MatrixXd& G) {
  Eigen::VectorXd v = Eigen::VectorXd::Ones(G.rows());
  for (int it = 0; it < 60; ++it) {
    Eigen::VectorXd w = G * v;
    const double nw = w.maxCoeff();
    if (!(nw > 0)) break;
    v = w / nw;
  }
  const double vmax = v.maxCoeff();
  for (Eigen::Index i = 0; i < v.size(); ++i) v(i) = std::max(v(i), 1e-9 * vmax) / vmax;
  return v;
}

// s += sum_j b[j] v_j in balls (the doubles are exact; the products and sums are enclosed).
void add_row_times(arb_ptr s, const double* b, const Eigen::VectorXd& v, std::size_t count) {
  arb_t bj, vj;
  arb_init(bj);
  arb_init(vj);
  for (std::size_t j = 0; j < count; ++j) {
    arb_set_d(bj, b[j]);
    arb_set_d(vj, v(static_cast<Eigen::Index>(j)));
    arb_addmul(s, bj, vj, kPrec);
  }
  arb_clear(bj);
  arb_clear(vj);
}

// max_i (B v)_i / v_i in balls, rounded up (B n x n, row stride c).
double symmetric_ratio_bound(const std::vector<double>& B, const Eigen::VectorXd& v, std::size_t n,
                             std::size_t c) {
  BallVec acc(1);
  arb_ptr s = acc[0];
  double worst = 0;
  for (std::size_t i = 0; i < n; ++i) {
    arb_zero(s);
    add_row_times(s, &B[i * c], v, n);
    arb_t vi;
    arb_init(vi);
    arb_set_d(vi, v(static_cast<Eigen::Index>(i)));
    arb_div(s, s, vi, kPrec);
    arb_clear(vi);
    worst = std::max(worst, detail::upper(s));
  }
  return worst;
}

// max_j (B' B v)_j / v_j in balls, rounded up (B r x c).
double gram_ratio_bound(const std::vector<double>& B, const Eigen::VectorXd& v, std::size_t r,
                        std::size_t c) {
  BallVec t(r), w(c);
  double worst = 0;
  for (std::size_t i = 0; i < r; ++i) {  // t = B v
    arb_zero(t[i]);
    add_row_times(t[i], &B[i * c], v, c);
  }
  for (std::size_t j = 0; j < c; ++j) {  // w = B' t, ratio
    arb_zero(w[j]);
    for (std::size_t i = 0; i < r; ++i) {
      arb_t bij;
      arb_init(bij);
      arb_set_d(bij, B[i * c + j]);
      arb_addmul(w[j], bij, t[i], kPrec);
      arb_clear(bij);
    }
    arb_t vj;
    arb_init(vj);
    arb_set_d(vj, v(static_cast<Eigen::Index>(j)));
    arb_div(w[j], w[j], vj, kPrec);
    arb_clear(vj);
    worst = std::max(worst, detail::upper(w[j]));
  }
  return worst;
}

// Rigorous upper bound of the spectral radius of B'B (B r x c, entries >= 0 as doubles) by
// Collatz-Wielandt with a power-iteration vector. With `symmetric` (B symmetric, r == c):
// of the spectral radius of B itself.
double cw_bound(const std::vector<double>& B, std::size_t r, std::size_t c, bool symmetric) {
  Eigen::MatrixXd M(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c));
  for (std::size_t i = 0; i < r; ++i)
    for (std::size_t j = 0; j < c; ++j)
      M(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)) = B[i * c + j];
  if (M.maxCoeff() <= 0) return 0;
  const Eigen::MatrixXd G = symmetric ? M : Eigen::MatrixXd(M.transpose() * M);
  const Eigen::VectorXd v = perron_vector(G);
  // In balls: w = G v (G = B'B or B), ratio_i = w_i / v_i.
  return symmetric ? symmetric_ratio_bound(B, v, r, c) : gram_ratio_bound(B, v, r, c);
}

// Is mu I - G positive definite (G symmetric n x n, given as balls)? Proven by Arb's Cholesky.
bool verify_upper_eig(const ArbMat& G, std::size_t n, double mu) {
  ArbMat X(static_cast<slong>(n), static_cast<slong>(n)),
      L(static_cast<slong>(n), static_cast<slong>(n));
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = 0; j < n; ++j) {
      arb_ptr x = arb_mat_entry(X.m, i, j);
      arb_neg(x, arb_mat_entry(G.m, i, j));
      if (i == j) {
        arb_t m;
        arb_init(m);
        arb_set_d(m, mu);
        arb_add(x, x, m, kPrec);
        arb_clear(m);
      }
    }
  return arb_mat_cho(L.m, X.m, kPrec) != 0;
}

// Rigorous upper bound of lambda_max of the symmetric ball matrix G whose radii are tiny.
double point_lambda_max(const ArbMat& G, std::size_t n) {
  Eigen::MatrixXd A(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(n));
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = 0; j < n; ++j)
      A(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)) =
          arf_get_d(arb_midref(arb_mat_entry(G.m, i, j)), ARF_RND_NEAR);
  A = 0.5 * (A + A.transpose()).eval();
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(A, Eigen::EigenvaluesOnly);
  const double lam = es.eigenvalues().maxCoeff();
  const double scale = std::max(es.eigenvalues().cwiseAbs().maxCoeff(), 1e-300);
  double eps = 1e-13 * scale;
  for (int k = 0; k < 8; ++k, eps *= 100)
    if (verify_upper_eig(G, n, lam + eps)) return lam + eps;
  return kInf;
}

// Upper bound of ||M||_2 for an r x c ball matrix (row-major in `b`).
double norm_upper(const BallVec& b, std::size_t r, std::size_t c) {
  std::vector<double> mag(r * c), rad(r * c), mid(r * c);
  arb_t t;
  arb_init(t);
  for (std::size_t k = 0; k < r * c; ++k) {
    mag[k] = detail::abs_upper(b[k]);
    mid[k] = arf_get_d(arb_midref(b[k]), ARF_RND_NEAR);
    arb_set_d(t, mid[k]);
    arb_sub(t, b[k], t, kPrec);
    rad[k] = detail::abs_upper(t);
  }
  arb_clear(t);
  for (double v : mag)
    if (!std::isfinite(v)) return kInf;
  const double a = std::sqrt(cw_bound(mag, r, c, false));
  // ||mid|| + ||rad||: ||mid||^2 = lambda_max(mid' mid), verified.
  ArbMat G(static_cast<slong>(c), static_cast<slong>(c));
  arb_t x, y;
  arb_init(x);
  arb_init(y);
  for (std::size_t i = 0; i < c; ++i)
    for (std::size_t j = 0; j < c; ++j) {
      arb_ptr g = arb_mat_entry(G.m, i, j);
      arb_zero(g);
      for (std::size_t k = 0; k < r; ++k) {
        arb_set_d(x, mid[k * c + i]);
        arb_set_d(y, mid[k * c + j]);
        arb_addmul(g, x, y, kPrec);
      }
    }
  arb_clear(x);
  arb_clear(y);
  const double lm = point_lambda_max(G, c);
  double bnd = a;
  if (std::isfinite(lm)) {
    arb_t s, q;
    arb_init(s);
    arb_init(q);
    arb_set_d(s, std::max(lm, 0.0));
    arb_sqrt(s, s, kPrec);
    arb_set_d(q, cw_bound(rad, r, c, false));
    arb_sqrt(q, q, kPrec);
    arb_add(s, s, q, kPrec);
    bnd = std::min(bnd, detail::upper(s));
    arb_clear(s);
    arb_clear(q);
  }
  return bnd;
}

// Upper bound of lambda_max for a symmetric n x n ball matrix (row-major in `b`).
double lambda_max_upper(const BallVec& b, std::size_t n) {
  // Gershgorin.
  double gersh = -kInf;
  arb_t s, t;
  arb_init(s);
  arb_init(t);
  for (std::size_t i = 0; i < n; ++i) {
    arb_set(s, b[i * n + i]);
    for (std::size_t j = 0; j < n; ++j) {
      if (j == i) continue;
      arb_set_d(t, detail::abs_upper(b[i * n + j]));
      arb_add(s, s, t, kPrec);
    }
    gersh = std::max(gersh, detail::upper(s));
  }
  // lambda_max(mid) + ||rad||_2 (Weyl). mid and rad are made exactly symmetric: Arb's Cholesky
  // reads the lower triangle only, and ||rad||_2 = rho(rad) (Collatz-Wielandt) needs symmetry.
  std::vector<double> rad(n * n);
  ArbMat M(static_cast<slong>(n), static_cast<slong>(n));
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = i; j < n; ++j) {
      const double m = arf_get_d(arb_midref(b[i * n + j]), ARF_RND_NEAR);
      arb_set_d(arb_mat_entry(M.m, i, j), m);
      arb_set_d(arb_mat_entry(M.m, j, i), m);
      arb_set_d(t, m);
      arb_sub(t, b[i * n + j], t, kPrec);
      double r = detail::abs_upper(t);
      arb_set_d(t, m);
      arb_sub(t, b[j * n + i], t, kPrec);
      r = std::max(r, detail::abs_upper(t));
      rad[i * n + j] = rad[j * n + i] = r;
    }
  double bnd = gersh;
  const double lm = point_lambda_max(M, n);
  if (std::isfinite(lm)) {
    arb_set_d(s, lm);
    arb_set_d(t, cw_bound(rad, n, n, true));
    arb_add(s, s, t, kPrec);
    bnd = std::min(bnd, detail::upper(s));
  }
  arb_clear(s);
  arb_clear(t);
  return bnd;
}

std::vector<ex> flatten(const GiNaC::matrix& M, bool symmetrize) {
  std::vector<ex> out;
  for (unsigned i = 0; i < M.rows(); ++i)
    for (unsigned j = 0; j < M.cols(); ++j)
      out.push_back(symmetrize ? ex((M(i, j) + M(j, i)) / 2) : M(i, j));
  return out;
}

std::vector<double> lows(const Box& b) {
  std::vector<double> v;
  for (const auto& r : b.ranges) v.push_back(r.lo);
  return v;
}

void check_box(const Box& box) {
  if (box.vars.size() != box.ranges.size())
    throw std::invalid_argument("certify: box with " + std::to_string(box.vars.size()) +
                                " variables and " + std::to_string(box.ranges.size()) + " ranges");
  for (std::size_t k = 0; k < box.ranges.size(); ++k)
    if (!(box.ranges[k].lo <= box.ranges[k].hi))
      throw std::invalid_argument("certify: empty or invalid range for '" + box.vars[k].get_name() +
                                  "'");
}

std::string arb_method(const BBResult& r) {
  return fmt::format("Arb balls, {} boxes", r.boxes);
}

std::string sampled_method(const std::string& sampled, const std::string& why) {
  return fmt::format("{} ({})", sampled, why);
}

// Max over sample points of a scalar function of the output values.
template <class F>
Bound sampled_max(const PointEval& pe, const Box& box, std::size_t samples, F score) {
  Bound b;
  b.kind = BoundKind::sampled;
  b.value = -kInf;
  const auto pts = sample_points(box, std::max<std::size_t>(samples, 1));
  std::size_t undefined = 0;
  for (const auto& p : pts) {
    const double v = score(pe(p));
    if (std::isnan(v)) {  // undefined there (0/0, a pole): not a value of the function
      ++undefined;
      continue;
    }
    if (v > b.value || b.worst_point.empty()) {
      b.value = v;
      b.worst_point = p;
    }
  }
  if (b.worst_point.empty()) {
    b.value = std::nan("");
    b.worst_point = pts.front();
  }
  b.method = undefined ? fmt::format("sampled, {} points, {} of them undefined and skipped",
                                     pts.size(), undefined)
                       : fmt::format("sampled, {} points", pts.size());
  return b;
}

double spectral_norm_d(const std::vector<double>& v, std::size_t r, std::size_t c) {
  Eigen::MatrixXd M(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c));
  for (std::size_t i = 0; i < r; ++i)
    for (std::size_t j = 0; j < c; ++j) {
      if (std::isnan(v[i * c + j])) return std::nan("");
      M(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)) = v[i * c + j];
    }
  if (r == 0 || c == 0) return 0;
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(M);
  return svd.singularValues()(0);
}

double lambda_max_d(const std::vector<double>& v, std::size_t n) {
  Eigen::MatrixXd M(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(n));
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = 0; j < n; ++j) {
      if (std::isnan(v[i * n + j])) return std::nan("");
      M(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)) = v[i * n + j];
    }
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(M, Eigen::EigenvaluesOnly);
  return es.eigenvalues().maxCoeff();
}

// Common driver: rigorous by branch and bound when the tape evaluates, else sampled.
Bound drive(const std::vector<ex>& outs, const Box& box, const EnclosureBudget& budget,
            const std::function<double(const BallVec&)>& ub_of_balls,
            const std::function<double(const std::vector<double>&)>& score) {
  check_box(box);
  BoxEnclosure enc(outs, box);
  const Tape& tape = enc.tape();
  PointEval pe(outs, box, tape);
  if (tape.supported()) {
    BallVec balls(outs.size());
    Objective obj;
    obj.upper = [&](const std::vector<double>& lo, const std::vector<double>& hi) {
      if (!enc.eval(lo, hi, balls)) return kInf;
      return ub_of_balls(balls);
    };
    obj.at = [&](const std::vector<double>& p) { return score(pe(p)); };
    const BBResult r = branch_and_bound(box, obj, enc.capped(budget), true, {}, tape.used_vars());
    if (std::isfinite(r.upper)) {
      Bound b;
      b.kind = BoundKind::rigorous;
      b.value = r.upper;
      b.worst_point = r.best_point.empty() ? lows(box) : r.best_point;
      b.method = arb_method(r);
      return b;
    }
    Bound b = sampled_max(pe, box, 4096, score);
    b.method =
        sampled_method(b.method, fmt::format("Arb could not bound it on {} boxes: a pole or a "
                                             "branch cut in the box?",
                                             r.boxes));
    return b;
  }
  Bound b = sampled_max(pe, box, 4096, score);
  b.method = sampled_method(b.method, "no ball arithmetic for " + tape.why());
  return b;
}

}  // namespace

const char* bound_kind_name(BoundKind k) {
  return k == BoundKind::rigorous ? "rigorous" : "sampled";
}

Box model_box(const Model& m) {
  Box b;
  for (const auto& s : m.all_symbols()) {
    const Interval iv = m.box(s);
    b.vars.push_back(s);
    b.ranges.push_back({detail::rational_lower(iv.lo), detail::rational_upper(iv.hi)});
  }
  return b;
}

Bound sup_abs(const ex& e, const Box& box, const EnclosureBudget& budget) {
  return drive(
      {e}, box, budget, [](const BallVec& b) { return detail::abs_upper(b[0]); },
      [](const std::vector<double>& v) { return std::fabs(v[0]); });
}

Bound sup_abs_sampled(const ex& e, const Box& box, std::size_t samples) {
  check_box(box);
  const std::vector<ex> outs{e};
  Tape tape(outs, box.vars);
  PointEval pe(outs, box, tape);
  return sampled_max(pe, box, samples,
                     [](const std::vector<double>& v) { return std::fabs(v[0]); });
}

Bound matrix_norm_bound(const GiNaC::matrix& M, const Box& box, const EnclosureBudget& budget) {
  const std::size_t r = M.rows(), c = M.cols();
  return drive(
      flatten(M, false), box, budget, [r, c](const BallVec& b) { return norm_upper(b, r, c); },
      [r, c](const std::vector<double>& v) { return spectral_norm_d(v, r, c); });
}

Bound lipschitz_bound(const std::vector<ex>& phi, const std::vector<GiNaC::symbol>& x,
                      const Box& box, const EnclosureBudget& budget) {
  GiNaC::matrix J(static_cast<unsigned>(phi.size()), static_cast<unsigned>(x.size()));
  for (std::size_t i = 0; i < phi.size(); ++i)
    for (std::size_t j = 0; j < x.size(); ++j)
      J(static_cast<unsigned>(i), static_cast<unsigned>(j)) = phi[i].diff(x[j]);
  return matrix_norm_bound(J, box, budget);
}

namespace {

// The eigenvector of the largest eigenvalue of the symmetric n x n matrix v (row-major).
Eigen::VectorXd top_eigenvector(const std::vector<double>& v, std::size_t n) {
  Eigen::MatrixXd M(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(n));
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = 0; j < n; ++j)
      M(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)) = v[i * n + j];
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(M);
  Eigen::Index top = 0;
  es.eigenvalues().maxCoeff(&top);
  return es.eigenvectors().col(top);
}

// Whether ev' S ev >= 0 is proven in ball arithmetic, S an n x n matrix of balls (row-major).
bool quadratic_form_nonnegative(const BallVec& S, const Eigen::VectorXd& ev, std::size_t n) {
  arb_t q, t;
  arb_init(q);
  arb_init(t);
  arb_zero(q);
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = 0; j < n; ++j) {
      arb_set_d(t, ev(static_cast<Eigen::Index>(i)) * 1.0);
      arb_mul(t, t, S[i * n + j], kPrec);
      arb_t vj;
      arb_init(vj);
      arb_set_d(vj, ev(static_cast<Eigen::Index>(j)));
      arb_mul(t, t, vj, kPrec);
      arb_clear(vj);
      arb_add(q, q, t, kPrec);
    }
  const bool proven = arb_is_nonnegative(q);
  arb_clear(q);
  arb_clear(t);
  return proven;
}

// Failure proven at the point: v' S(p) v >= 0 in balls for the top eigenvector v of S(p).
bool failure_proven_at(const std::vector<double>& point, PointEval& pe, Tape& tape, std::size_t n,
                       std::size_t outputs) {
  const Eigen::VectorXd ev = top_eigenvector(pe(point), n);
  BallVec pb(outputs);
  return tape.eval_point(point, pb) && quadratic_form_nonnegative(pb, ev, n);
}

// The verdict by branch and bound of lambda_max over the box: rigorous when the upper bound
// is negative or failure is proven at the worst point, else sampled.
DefinitenessVerdict enclosure_verdict(BoxEnclosure& enc, PointEval& pe, std::size_t n,
                                      std::size_t outputs, const Box& box,
                                      const EnclosureBudget& budget) {
  Tape& tape = const_cast<Tape&>(enc.tape());
  DefinitenessVerdict out;
  BallVec balls(outputs);
  Objective obj;
  obj.upper = [&](const std::vector<double>& lo, const std::vector<double>& hi) {
    if (!enc.eval(lo, hi, balls)) return kInf;
    return lambda_max_upper(balls, n);
  };
  obj.at = [&](const std::vector<double>& p) { return lambda_max_d(pe(p), n); };
  const BBResult r = branch_and_bound(
      box, obj, enc.capped(budget), false,
      [&budget](double ub, double best) {
        // The sign is decided (proven negative, or a point with lambda_max >= 0) and the bound
        // is tight, so the worst point is the worst within relative_gap.
        const bool tight = ub - best <= std::max(budget.relative_gap * std::fabs(best), 1e-12);
        return tight && (ub < 0 || best >= 0);
      },
      tape.used_vars());
  out.worst_point = r.best_point;
  if (std::isfinite(r.upper) && r.upper < 0) {
    out.holds = true;
    out.kind = BoundKind::rigorous;
    out.max_eigenvalue_bound = r.upper;
    out.method =
        fmt::format("Arb balls, Gershgorin / midpoint-radius eigenvalue bounds, {} boxes", r.boxes);
    return out;
  }
  if (!r.best_point.empty() && r.best >= 0 &&
      failure_proven_at(r.best_point, pe, tape, n, outputs)) {
    out.holds = false;
    out.kind = BoundKind::rigorous;
    out.max_eigenvalue_bound = r.upper;
    out.method = fmt::format(
        "Arb balls: fails at the worst point (v'Sv >= 0 verified in balls, lambda_max there "
        "~ {:.6g}); {} boxes",
        r.best, r.boxes);
    return out;
  }
  out.holds = r.best < 0;
  out.kind = BoundKind::sampled;
  out.max_eigenvalue_bound = r.best;
  out.method = fmt::format(
      "sampled verdict: enclosure undecided after {} boxes (upper bound {:.6g}, largest "
      "eigenvalue found {:.6g})",
      r.boxes, r.upper, r.best);
  return out;
}

}  // namespace

DefinitenessVerdict negative_definite(const GiNaC::matrix& S, const Box& box,
                                      const EnclosureBudget& budget) {
  check_box(box);
  if (S.rows() != S.cols())
    throw std::invalid_argument("certify: negative_definite of a non-square matrix");
  const std::size_t n = S.rows();
  const std::vector<ex> outs = flatten(S, true);
  BoxEnclosure enc(outs, box);
  Tape& tape = const_cast<Tape&>(enc.tape());
  PointEval pe(outs, box, tape);
  if (tape.supported()) return enclosure_verdict(enc, pe, n, outs.size(), box, budget);
  auto score = [n](const std::vector<double>& v) { return lambda_max_d(v, n); };
  const Bound b = sampled_max(pe, box, 4096, score);
  DefinitenessVerdict out;
  out.holds = b.value < 0;
  out.kind = BoundKind::sampled;
  out.max_eigenvalue_bound = b.value;
  out.worst_point = b.worst_point;
  out.method = sampled_method(b.method, "no ball arithmetic for " + tape.why());
  return out;
}

}  // namespace obsynth::certify
