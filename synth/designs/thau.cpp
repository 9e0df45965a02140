#include "designs/thau.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include "certify/enclosure.hpp"
#include "designs/design_helpers.hpp"
#include "designs/options.hpp"
#include "front/fresh_names.hpp"
#include "symbolic/dag.hpp"
#include "symbolic/expr_print.hpp"
#include "symbolic/symbolic.hpp"

namespace obsynth {

using GiNaC::ex;
using GiNaC::numeric;

namespace lyapunov_tools {

numeric exact_of_double(double v) {
  if (v == 0 || !std::isfinite(v)) return 0;
  int e = 0;
  const double mant = std::frexp(v, &e);  // v = mant 2^e, 1/2 <= |mant| < 1
  const long mi = static_cast<long>(std::ldexp(mant, 53));
  e -= 53;
  const numeric two(2);
  return e >= 0 ? numeric(mi) * two.power(e) : numeric(mi) / two.power(-e);
}

numeric round_rational(double v, int digits) {
  if (v == 0 || !std::isfinite(v)) return 0;
  const int k = digits - 1 - static_cast<int>(std::floor(std::log10(std::fabs(v))));
  const double scaled = std::round(v * std::pow(10.0, k));
  const numeric ten(10);
  const numeric s(static_cast<long>(scaled));
  return k >= 0 ? s / ten.power(k) : s * ten.power(-k);
}

numeric round_absolute(double v, double per_unit) {
  if (!std::isfinite(v)) return 0;
  return numeric(static_cast<long>(std::round(v * per_unit))) /
         numeric(static_cast<long>(per_unit));
}

numeric exact_value(const ex& e, const std::string& what) {
  const ex v = simplify(e);
  if (GiNaC::is_a<numeric>(v) && GiNaC::ex_to<numeric>(v).is_rational())
    return GiNaC::ex_to<numeric>(v);
  const ex f = GiNaC::evalf(v);
  if (GiNaC::is_a<numeric>(f) && GiNaC::ex_to<numeric>(f).is_real())
    return exact_of_double(GiNaC::ex_to<numeric>(f).to_double());
  throw UserError(SourceLoc{}, fmt::format("{} = {} is not a real number", what, to_string(v)));
}

std::optional<Eigen::VectorXd> place_poles(const Eigen::MatrixXd& A, const Eigen::RowVectorXd& c,
                                           const std::vector<double>& poles) {
  const Eigen::Index n = A.rows();
  Eigen::MatrixXd O(n, n);
  Eigen::RowVectorXd row = c;
  for (Eigen::Index k = 0; k < n; ++k) {
    O.row(k) = row;
    row = row * A;
  }
  Eigen::FullPivLU<Eigen::MatrixXd> lu(O);
  if (lu.rank() < n) return std::nullopt;
  // Dual pair (A^T, c^T): K = e_n^T Ctrb^-1 p(A^T), Ctrb = O^T; then L = -K^T.
  Eigen::MatrixXd pA = Eigen::MatrixXd::Identity(n, n);
  const Eigen::MatrixXd At = A.transpose();
  for (double p : poles) pA = pA * (At - p * Eigen::MatrixXd::Identity(n, n));
  const Eigen::MatrixXd Ctrb = O.transpose();
  Eigen::RowVectorXd en = Eigen::RowVectorXd::Zero(n);
  en(n - 1) = 1;
  const Eigen::RowVectorXd sol = Ctrb.transpose().fullPivLu().solve(en.transpose()).transpose();
  const Eigen::RowVectorXd K = sol * pA;
  return Eigen::VectorXd(-K.transpose());
}

std::vector<numeric> place_poles_exact(const GiNaC::matrix& A, const GiNaC::matrix& c,
                                       const std::vector<numeric>& poles) {
  const unsigned n = A.rows();
  const GiNaC::matrix O = linear_observability_matrix(A, c);
  if (O.determinant().is_zero()) return {};
  const GiNaC::matrix At = A.transpose();
  GiNaC::matrix pA = GiNaC::ex_to<GiNaC::matrix>(GiNaC::unit_matrix(n));
  for (const auto& p : poles)
    pA = pA.mul(At.sub(GiNaC::ex_to<GiNaC::matrix>(GiNaC::unit_matrix(n)).mul_scalar(p)));
  const GiNaC::matrix Ctrb = O.transpose();
  GiNaC::matrix en(1, n);
  en(0, n - 1) = 1;
  const GiNaC::matrix K = en.mul(Ctrb.inverse()).mul(pA);
  std::vector<numeric> L;
  for (unsigned i = 0; i < n; ++i) L.push_back(GiNaC::ex_to<numeric>(GiNaC::normal(-K(0, i))));
  return L;
}

std::optional<Eigen::MatrixXd> solve_lyapunov(const Eigen::MatrixXd& AL, const Eigen::MatrixXd& Q) {
  const Eigen::Index n = AL.rows();
  const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(n, n);
  Eigen::MatrixXd M = Eigen::MatrixXd::Zero(n * n, n * n);
  const Eigen::MatrixXd At = AL.transpose();
  // vec(At P) = (I (x) At) vec P, vec(P AL) = (At (x) I) vec P, column-major vec.
  for (Eigen::Index i = 0; i < n; ++i)
    for (Eigen::Index j = 0; j < n; ++j) {
      M.block(i * n, j * n, n, n) += I(i, j) * At;
      M.block(i * n, j * n, n, n) += At(i, j) * I;
    }
  Eigen::VectorXd rhs(n * n);
  for (Eigen::Index j = 0; j < n; ++j)
    for (Eigen::Index i = 0; i < n; ++i) rhs(j * n + i) = -2 * Q(i, j);
  Eigen::FullPivLU<Eigen::MatrixXd> lu(M);
  if (!lu.isInvertible()) return std::nullopt;
  const Eigen::VectorXd v = lu.solve(rhs);
  Eigen::MatrixXd P(n, n);
  for (Eigen::Index j = 0; j < n; ++j)
    for (Eigen::Index i = 0; i < n; ++i) P(i, j) = v(j * n + i);
  return Eigen::MatrixXd((P + P.transpose()) / 2);
}

std::optional<GiNaC::matrix> solve_lyapunov_exact(const GiNaC::matrix& AL, const GiNaC::matrix& Q) {
  const unsigned n = AL.rows();
  GiNaC::matrix P(n, n);
  GiNaC::lst vars, eqs;
  for (unsigned i = 0; i < n; ++i)
    for (unsigned j = i; j < n; ++j) {
      GiNaC::symbol s(fmt::format("p{}_{}", i, j));
      P(i, j) = s;
      P(j, i) = s;
      vars.append(s);
    }
  const GiNaC::matrix R = AL.transpose().mul(P).add(P.mul(AL)).add(Q.mul_scalar(2));
  for (unsigned i = 0; i < n; ++i)
    for (unsigned j = i; j < n; ++j) eqs.append(R(i, j) == 0);
  ex sol;
  try {
    sol = GiNaC::lsolve(eqs, vars, GiNaC::solve_algo::gauss);
  } catch (const std::exception&) {
    return std::nullopt;
  }
  if (!GiNaC::is_a<GiNaC::lst>(sol) || sol.nops() != vars.nops()) return std::nullopt;
  GiNaC::matrix out = GiNaC::ex_to<GiNaC::matrix>(ex(P).subs(sol));
  for (unsigned i = 0; i < n; ++i)
    for (unsigned j = 0; j < n; ++j)
      if (!GiNaC::is_a<numeric>(out(i, j))) return std::nullopt;
  return out;
}

std::vector<std::vector<double>> box_samples(const std::vector<std::pair<double, double>>& ranges,
                                             std::size_t count) {
  static const int primes[] = {2,  3,  5,  7,  11, 13, 17, 19, 23, 29, 31, 37, 41,
                               43, 47, 53, 59, 61, 67, 71, 73, 79, 83, 89, 97};
  const std::size_t d = ranges.size();
  std::vector<std::vector<double>> out;
  auto at = [&](const std::vector<double>& t) {
    std::vector<double> p(d);
    for (std::size_t i = 0; i < d; ++i)
      p[i] = ranges[i].first + t[i] * (ranges[i].second - ranges[i].first);
    return p;
  };
  if (d <= 10)
    for (std::size_t mask = 0; mask < (std::size_t{1} << d) && out.size() < count; ++mask) {
      std::vector<double> t(d);
      for (std::size_t i = 0; i < d; ++i) t[i] = (mask >> i) & 1 ? 1.0 : 0.0;
      out.push_back(at(t));
    }
  if (out.size() < count) out.push_back(at(std::vector<double>(d, 0.5)));
  for (std::size_t k = 1; out.size() < count; ++k) {
    std::vector<double> t(d);
    for (std::size_t i = 0; i < d; ++i) {
      const int b = primes[i % 25];
      double f = 1, r = 0;
      for (std::size_t q = k; q > 0; q /= static_cast<std::size_t>(b)) {
        f /= b;
        r += f * static_cast<double>(q % static_cast<std::size_t>(b));
      }
      t[i] = r;
    }
    out.push_back(at(t));
  }
  return out;
}

std::vector<double> nelder_mead(const std::function<double(const std::vector<double>&)>& f,
                                std::vector<double> x0, double step, int max_evals) {
  const std::size_t d = x0.size();
  if (d == 0) return x0;
  std::vector<std::vector<double>> pts(d + 1, x0);
  std::vector<double> val(d + 1);
  for (std::size_t i = 0; i < d; ++i) pts[i + 1][i] += step;
  int evals = 0;
  auto F = [&](const std::vector<double>& x) {
    ++evals;
    const double v = f(x);
    return std::isfinite(v) ? v : std::numeric_limits<double>::max();
  };
  for (std::size_t i = 0; i <= d; ++i) val[i] = F(pts[i]);
  while (evals < max_evals) {
    std::vector<std::size_t> idx(d + 1);
    for (std::size_t i = 0; i <= d; ++i) idx[i] = i;
    std::stable_sort(idx.begin(), idx.end(), [&](auto a, auto b) { return val[a] < val[b]; });
    const std::size_t best = idx[0], worst = idx[d], second = idx[d - 1];
    if (std::fabs(val[worst] - val[best]) < 1e-12 * (1 + std::fabs(val[best]))) break;
    std::vector<double> c(d, 0);
    for (std::size_t i = 0; i <= d; ++i)
      if (i != worst)
        for (std::size_t j = 0; j < d; ++j) c[j] += pts[i][j] / static_cast<double>(d);
    auto towards = [&](double t) {
      std::vector<double> p(d);
      for (std::size_t j = 0; j < d; ++j) p[j] = c[j] + t * (pts[worst][j] - c[j]);
      return p;
    };
    const auto r = towards(-1);
    const double fr = F(r);
    if (fr < val[best]) {
      const auto e = towards(-2);
      const double fe = F(e);
      if (fe < fr)
        pts[worst] = e, val[worst] = fe;
      else
        pts[worst] = r, val[worst] = fr;
    } else if (fr < val[second]) {
      pts[worst] = r, val[worst] = fr;
    } else {
      const auto k = towards(0.5);
      const double fk = F(k);
      if (fk < val[worst]) {
        pts[worst] = k, val[worst] = fk;
      } else {
        for (std::size_t i = 0; i <= d; ++i)
          if (i != best) {
            for (std::size_t j = 0; j < d; ++j) pts[i][j] = (pts[i][j] + pts[best][j]) / 2;
            val[i] = F(pts[i]);
          }
      }
    }
  }
  const auto it = std::min_element(val.begin(), val.end());
  return pts[static_cast<std::size_t>(it - val.begin())];
}

std::vector<std::vector<double>> candidate_pole_sets(std::size_t n) {
  std::vector<std::vector<double>> out;
  for (double scale : {0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0})
    for (int shape = 0; shape < 3; ++shape) {
      std::vector<double> p;
      for (std::size_t k = 0; k < n; ++k) {
        const double kk = static_cast<double>(k);
        p.push_back(-scale * (shape == 0 ? 1 + kk / 2 : shape == 1 ? 1 + kk : 1.0));
      }
      out.push_back(p);
    }
  return out;
}

Eigen::MatrixXd to_eigen(const GiNaC::matrix& M) {
  Eigen::MatrixXd E(M.rows(), M.cols());
  for (unsigned i = 0; i < M.rows(); ++i)
    for (unsigned j = 0; j < M.cols(); ++j)
      E(i, j) = GiNaC::ex_to<numeric>(GiNaC::evalf(M(i, j))).to_double();
  return E;
}

std::string matrix_text(const Eigen::MatrixXd& M, int digits) {
  std::vector<std::string> rows;
  for (Eigen::Index i = 0; i < M.rows(); ++i) {
    std::vector<std::string> r;
    for (Eigen::Index j = 0; j < M.cols(); ++j)
      r.push_back(fmt::format("{:.{}g}", M(i, j), digits));
    rows.push_back(fmt::format("[{}]", fmt::join(r, ", ")));
  }
  return fmt::format("[{}]", fmt::join(rows, ", "));
}

}  // namespace lyapunov_tools

namespace {

using namespace lyapunov_tools;

constexpr int kRegionBisections = 14;  // smallest sub-box tried: 2^-14 of the domain
// The sub-box is the largest found with M <= kRegionTarget sigma_min(Q)/sigma_max(P), so that
// the certified margin (and the guaranteed decay rate) is not vanishingly small.
constexpr double kRegionTarget = 0.9;
// Searched poles stay in [-kMaxPole, -kMinPole] (the grid's largest scale is 32 x the shape);
// fast poles buy little certificate and cost noise gain and integration step.
constexpr double kMinPole = 0.05, kMaxPole = 20;
constexpr double kPolePenalty = 1e-4;
// Past kExhaustiveStates states the search and the region take their budgeted forms (models
// with n <= 4, the bundled ones among them, keep the exhaustive ones and their outputs):
// - Q = I unless given. For Hurwitz A_L the solution of A_L^T P + P A_L = -2 Q is
//   P_Q = 2 int_0^inf e^(A_L^T t) Q e^(A_L t) dt, monotone in Q; Q >= sigma_min(Q) I gives
//   P_Q >= sigma_min(Q) P_I, so sigma_min(Q)/sigma_max(P_Q) <= 1/sigma_max(P_I): no Q beats I,
//   and only the poles are searched (grid, then Nelder-Mead on their log magnitudes);
// - the region's scale is bisected on the sampled M (kBisectionSamples points per scale), and
//   the rigorous enclosure runs on the chosen region only (shrunk by kShrink and run again when
//   it does not certify, at most kRigorousAttempts times), each under the work cap kWorkBudget
//   (ball operations, deterministic); the domain's enclosure is skipped when the sampled M
//   there already refutes (26).
constexpr std::size_t kExhaustiveStates = 4;
constexpr std::size_t kBisectionSamples = 512;
constexpr int kRigorousAttempts = 6;
constexpr double kShrink = 0.7;
constexpr std::size_t kWorkBudget = std::size_t{1} << 23;

// The exact split F(x, u) = A x + B u + phi(x, u), h(x) = C x + c0.
struct Split {
  std::string not_applicable;  // empty when the split exists
  std::vector<numeric> x_star, u_star;
  GiNaC::matrix A, B, C;
  ExVec c0, phi;
  std::size_t output = 0;  // output used for pole placement
};

std::string point_text(const std::vector<GiNaC::symbol>& s, const std::vector<numeric>& v) {
  std::vector<std::string> out;
  for (std::size_t i = 0; i < s.size(); ++i)
    out.push_back(fmt::format("{} = {}", s[i].get_name(), to_string(v[i])));
  return fmt::format("{}", fmt::join(out, ", "));
}

// The origin when the box holds it, else the box centre.
numeric expansion_coordinate(const Interval& b) {
  if (b.lo <= 0 && 0 <= b.hi) return 0;
  return (b.lo + b.hi) / 2;
}

// The expansion point (x*, u*) into s, and the substitution of it (parameters at their
// box centre).
GiNaC::exmap expansion_point(const Model& m, Split& s) {
  GiNaC::exmap at;
  for (const auto& x : m.states) {
    s.x_star.push_back(expansion_coordinate(m.box(x)));
    at[x] = s.x_star.back();
  }
  for (const auto& u : m.inputs) {
    s.u_star.push_back(expansion_coordinate(m.box(u)));
    at[u] = s.u_star.back();
  }
  for (const auto& q : m.free_params()) {
    const Interval b = m.box(q);
    at[q] = (b.lo + b.hi) / 2;
  }
  return at;
}

// y = C x + c0: h must be linear in x with constant coefficients. False (s.not_applicable
// set) when it is not.
bool linear_output(const Model& m, Split& s) {
  const std::size_t n = m.n(), p = m.p();
  s.C = GiNaC::matrix(static_cast<unsigned>(p), static_cast<unsigned>(n));
  GiNaC::exmap zero_x;
  for (const auto& x : m.states) zero_x[x] = 0;
  for (std::size_t i = 0; i < p; ++i) {
    for (std::size_t j = 0; j < n; ++j) {
      const ex d = simplify(m.h[i].diff(m.states[j]));
      if (!GiNaC::is_a<numeric>(d) || !GiNaC::ex_to<numeric>(d).is_real()) {
        s.not_applicable = fmt::format(
            "h is not linear in x: dh{}/d{} = {} is not a constant (Thau needs y = C x)",
            p > 1 ? std::to_string(i + 1) : std::string(), m.states[j].get_name(), to_string(d));
        return false;
      }
      s.C(i, j) = d;
    }
    s.c0.push_back(simplify(m.h[i].subs(zero_x)));
  }
  return true;
}

// F = A x + B u + phi with A, B the exact Jacobians at the expansion point. False
// (s.not_applicable set) when they are not exact numbers there.
bool linear_part(const Model& m, const ExVec& F, const GiNaC::exmap& at, Split& s) {
  const std::size_t n = m.n();
  s.A = GiNaC::matrix(static_cast<unsigned>(n), static_cast<unsigned>(n));
  s.B = GiNaC::matrix(static_cast<unsigned>(n), static_cast<unsigned>(m.m()));
  try {
    for (std::size_t i = 0; i < n; ++i) {
      for (std::size_t j = 0; j < n; ++j)
        s.A(i, j) = exact_value(
            F[i].diff(m.states[j]).subs(at),
            fmt::format("dF{}/d{} at the expansion point", i + 1, m.states[j].get_name()));
      for (std::size_t j = 0; j < m.m(); ++j)
        s.B(i, j) = exact_value(
            F[i].diff(m.inputs[j]).subs(at),
            fmt::format("dF{}/d{} at the expansion point", i + 1, m.inputs[j].get_name()));
    }
  } catch (const UserError& e) {
    s.not_applicable = fmt::format("no linear part at the expansion point ({}): {}",
                                   point_text(m.states, s.x_star), e.what());
    return false;
  }
  for (std::size_t i = 0; i < n; ++i) {
    ex lin = 0;
    for (std::size_t j = 0; j < n; ++j) lin += s.A(i, j) * m.states[j];
    for (std::size_t j = 0; j < m.m(); ++j) lin += s.B(i, j) * m.inputs[j];
    s.phi.push_back(simplify(F[i] - lin));
  }
  return true;
}

// Pole placement goes through one output with (c_i, A) observable: the first such output
// into s.output, else s.not_applicable says why none.
void choose_output(std::size_t n, std::size_t p, Split& s) {
  GiNaC::matrix Oall(static_cast<unsigned>(n * p), static_cast<unsigned>(n));
  for (std::size_t i = 0; i < p; ++i) {
    GiNaC::matrix row(1, static_cast<unsigned>(n));
    for (std::size_t j = 0; j < n; ++j) row(0, j) = s.C(i, j);
    GiNaC::matrix O(static_cast<unsigned>(n), static_cast<unsigned>(n));
    for (std::size_t k = 0; k < n; ++k) {
      for (std::size_t j = 0; j < n; ++j) {
        O(k, j) = row(0, j);
        Oall(k * p + i, j) = row(0, j);
      }
      row = row.mul(s.A);
    }
    if (!O.determinant().is_zero()) {
      s.output = i;
      return;
    }
  }
  const unsigned rank = Oall.rank();
  s.not_applicable =
      rank < n ? fmt::format("(C, A) is not observable at the expansion point: rank {} < n = {}",
                             rank, n)
               : "no single output makes (c_i, A) observable; multi-output pole placement is not "
                 "implemented";
}

Split split_model(const Model& m) {
  Split s;
  const ExVec F = m.field();
  const GiNaC::exmap at = expansion_point(m, s);
  if (!linear_output(m, s) || !linear_part(m, F, at, s)) return s;
  choose_output(m.n(), m.p(), s);
  return s;
}

struct Region {
  double scale = 1;  // 1: the declared domain
  certify::Box box;
  certify::Bound M;      // rigorous (or fallback) bound of sup ||D_x phi||_2 on the region
  double M_sampled = 0;  // sampled estimate
  std::vector<double> M_sampled_point;
};

struct Result {
  Split split;
  bool user_poles = false, user_Q = false, whole_domain_only = false;
  std::size_t choices_tried = 0;
  std::vector<numeric> poles;
  std::vector<numeric> L;  // n entries (column of the chosen output)
  GiNaC::matrix Q, P;
  bool P_exact = true;
  double lyapunov_residual = 0;
  double sigma_min_Q = 0, sigma_max_P = 0, ratio = 0;
  Region domain, region;  // region == domain when the condition holds there
  bool region_found = false;
  bool holds = false, rigorous = false;
  bool budgeted = false;   // n > kExhaustiveStates: Q = I, budgeted region search
  std::string not_proven;  // budgeted: why the enclosure did not certify what the samples say
  double margin() const { return ratio - region.M.value; }
  double domain_margin() const { return ratio - domain.M.value; }
};

// States that D_x phi depends on: only their ranges shrink with the region.
bool jacobian_depends_on(const Model& m, const Split& s, const GiNaC::symbol& x) {
  for (const auto& e : s.phi)
    for (const auto& xj : m.states)
      if (e.diff(xj).has(x)) return true;
  return false;
}

certify::Box scaled_box(const Model& m, const Split& s, double scale) {
  certify::Box b = certify::model_box(m);
  for (std::size_t k = 0; k < b.vars.size(); ++k)
    for (std::size_t i = 0; i < m.n(); ++i)
      if (b.vars[k].is_equal(m.states[i]) && jacobian_depends_on(m, s, m.states[i])) {
        const double c = s.x_star[i].to_double();
        b.ranges[k].lo = c + scale * (b.ranges[k].lo - c);
        b.ranges[k].hi = c + scale * (b.ranges[k].hi - c);
      }
  return b;
}

// Sampled sup ||D_x phi||_2 over the box (a lower estimate of the Lipschitz constant).
void sampled_lipschitz(const Model& m, const Split& s, Region& r, std::size_t count = 4096) {
  const std::size_t n = m.n();
  std::vector<ex> D;
  for (std::size_t j = 0; j < n; ++j)
    for (std::size_t i = 0; i < n; ++i) D.push_back(s.phi[i].diff(m.states[j]));
  std::vector<std::string> names;
  std::vector<std::pair<double, double>> ranges;
  for (std::size_t k = 0; k < r.box.vars.size(); ++k) {
    names.push_back(r.box.vars[k].get_name());
    ranges.emplace_back(r.box.ranges[k].lo, r.box.ranges[k].hi);
  }
  const NumericFunction fn(D, names);
  r.M_sampled = 0;
  for (const auto& pt : box_samples(ranges, count)) {
    const std::vector<double> v = fn(pt);
    Eigen::MatrixXd J(n, n);
    for (std::size_t j = 0; j < n; ++j)
      for (std::size_t i = 0; i < n; ++i)
        J(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)) = v[j * n + i];
    const double norm = J.jacobiSvd().singularValues()(0);
    if (norm > r.M_sampled || r.M_sampled_point.empty()) {
      r.M_sampled = norm;
      r.M_sampled_point = pt;
    }
  }
}

Region region_at(const Model& m, const Split& s, double scale, bool sampled_too) {
  Region r;
  r.scale = scale;
  r.box = scaled_box(m, s, scale);
  r.M = certify::lipschitz_bound(s.phi, m.states, r.box);
  if (sampled_too) sampled_lipschitz(m, s, r);
  return r;
}

// The budgeted form (n > kExhaustiveStates): the sampled M first (4096 points, or `count`),
// then the enclosure under kWorkBudget unless `rigorous` is false.
Region budgeted_region_at(const Model& m, const Split& s, double scale, bool rigorous,
                          std::size_t count = 4096) {
  Region r;
  r.scale = scale;
  r.box = scaled_box(m, s, scale);
  sampled_lipschitz(m, s, r, count);
  if (rigorous) {
    certify::EnclosureBudget budget;
    budget.max_work = kWorkBudget;
    r.M = certify::lipschitz_bound(s.phi, m.states, r.box, budget);
  } else {
    r.M.value = r.M_sampled;
    r.M.kind = certify::BoundKind::sampled;
    r.M.worst_point = r.M_sampled_point;
    r.M.method = fmt::format("sampled, {} points", count);
  }
  return r;
}

// Sample count of the bisection: the box's corners (up to 2^10) plus kBisectionSamples.
std::size_t bisection_samples(const Model& m) {
  const std::size_t d = m.all_symbols().size();
  return kBisectionSamples + (d <= 10 ? std::size_t{1} << d : 0);
}

// sigma_min(Q) / sigma_max(P) for P of eq. (21); -inf when A + L c is not Hurwitz.
double ratio_of(const Eigen::MatrixXd& AL, const Eigen::MatrixXd& Q) {
  const auto P = solve_lyapunov(AL, Q);
  if (!P) return -std::numeric_limits<double>::infinity();
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> ep(*P, Eigen::EigenvaluesOnly),
      eq(Q, Eigen::EigenvaluesOnly);
  const double pmin = ep.eigenvalues()(0), pmax = ep.eigenvalues()(P->rows() - 1);
  if (!(pmin > 0) || !(eq.eigenvalues()(0) > 0)) return -std::numeric_limits<double>::infinity();
  return eq.eigenvalues()(0) / pmax;
}

Eigen::MatrixXd Q_of(const std::vector<double>& r, std::size_t n) {
  Eigen::MatrixXd R =
      Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(n));
  std::size_t k = 0;
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = 0; j <= i; ++j)
      R(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)) = r[k++];
  return R * R.transpose();
}

std::vector<double> identity_factor(std::size_t n) {
  std::vector<double> r;
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = 0; j <= i; ++j) r.push_back(i == j ? 1.0 : 0.0);
  return r;
}

struct SearchOutcome {
  std::vector<double> poles;
  Eigen::MatrixXd Q;
  double ratio = -std::numeric_limits<double>::infinity();
  std::size_t tried = 0;
};

// A + L c with L placing the poles; nullopt when placement fails.
std::optional<Eigen::MatrixXd> closed_loop(const Eigen::MatrixXd& A, const Eigen::RowVectorXd& c,
                                           const std::vector<double>& poles) {
  const auto L = place_poles(A, c, poles);
  if (!L) return std::nullopt;
  return Eigen::MatrixXd(A + (*L) * c);
}

// The given Q, or the Q maximising the ratio for this A + L c (Nelder-Mead on Q's Cholesky
// factor from I), into o.Q and o.ratio.
void best_Q(const Eigen::MatrixXd& AL, const std::optional<Eigen::MatrixXd>& user_Q,
            SearchOutcome& o) {
  const std::size_t n = static_cast<std::size_t>(AL.rows());
  if (user_Q) {
    o.Q = *user_Q;
    o.ratio = ratio_of(AL, *user_Q);
    ++o.tried;
    return;
  }
  const auto r = nelder_mead(
      [&](const std::vector<double>& v) {
        ++o.tried;
        return -ratio_of(AL, Q_of(v, n));
      },
      identity_factor(n), 0.3, 60 * static_cast<int>(n * (n + 1) / 2 + 1));
  o.Q = Q_of(r, n);
  o.ratio = ratio_of(AL, o.Q);
}

// Joint Nelder-Mead refinement of the poles (log magnitudes, clamped to [kMinPole, kMaxPole])
// and Q (its Cholesky factor, unless given), from best; tried counts the evaluations.
SearchOutcome refine_search(const Eigen::MatrixXd& A, const Eigen::RowVectorXd& c,
                            const std::optional<Eigen::MatrixXd>& user_Q, const SearchOutcome& best,
                            std::size_t& tried) {
  const std::size_t n = static_cast<std::size_t>(A.rows());
  std::vector<double> v;
  for (double p : best.poles) v.push_back(std::log(-p));
  const std::size_t np = v.size();
  if (!user_Q) {
    Eigen::LLT<Eigen::MatrixXd> llt(best.Q);
    const Eigen::MatrixXd R = llt.matrixL();
    for (std::size_t i = 0; i < n; ++i)
      for (std::size_t j = 0; j <= i; ++j)
        v.push_back(R(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)));
  }
  auto unpack = [&](const std::vector<double>& w, std::vector<double>& poles, Eigen::MatrixXd& Q) {
    poles.clear();
    for (std::size_t k = 0; k < np; ++k)
      poles.push_back(-std::exp(std::clamp(w[k], std::log(kMinPole), std::log(kMaxPole))));
    Q = user_Q ? *user_Q : Q_of(std::vector<double>(w.begin() + static_cast<long>(np), w.end()), n);
  };
  const auto w = nelder_mead(
      [&](const std::vector<double>& w) {
        ++tried;
        std::vector<double> poles;
        Eigen::MatrixXd Q;
        unpack(w, poles, Q);
        const auto AL = closed_loop(A, c, poles);
        // A small price on fast poles: among near-equal certificates, the gentler gain.
        return AL ? -ratio_of(*AL, Q) + kPolePenalty * -poles.front()
                  : std::numeric_limits<double>::infinity();
      },
      v, 0.2, 150 * static_cast<int>(v.size() + 1));
  SearchOutcome o;
  unpack(w, o.poles, o.Q);
  if (const auto AL = closed_loop(A, c, o.poles)) o.ratio = ratio_of(*AL, o.Q);
  return o;
}

// Maximises sigma_min(Q)/sigma_max(P) over the free choices: a grid of pole sets (each with
// its best Q), then a joint refinement from the best grid point.
SearchOutcome search(const Eigen::MatrixXd& A, const Eigen::RowVectorXd& c,
                     const std::vector<double>& user_poles,
                     const std::optional<Eigen::MatrixXd>& user_Q) {
  const std::size_t n = static_cast<std::size_t>(A.rows());
  SearchOutcome best;
  const auto pole_sets =
      user_poles.empty() ? candidate_pole_sets(n) : std::vector<std::vector<double>>{user_poles};
  std::size_t tried = 0;
  for (const auto& poles : pole_sets) {
    if (user_poles.empty() && -*std::min_element(poles.begin(), poles.end()) > kMaxPole) continue;
    const auto AL = closed_loop(A, c, poles);
    if (!AL) continue;
    SearchOutcome o;
    o.poles = poles;
    best_Q(*AL, user_Q, o);
    tried += o.tried;
    if (o.ratio > best.ratio) best = o;
  }
  if (user_poles.empty() && std::isfinite(best.ratio)) {
    const SearchOutcome o = refine_search(A, c, user_Q, best, tried);
    if (o.ratio > best.ratio) {
      best.poles = o.poles;
      best.Q = o.Q;
      best.ratio = o.ratio;
    }
  }
  best.tried = tried;
  return best;
}

std::vector<double> chosen_poles(const DesignOptions& o, std::size_t n) {
  const auto poles = real_list_option(o, "thau-poles");
  if (poles.empty()) return {};
  if (poles.size() != n)
    throw UserError(
        SourceLoc{},
        fmt::format("--thau-poles: {} poles given, the model has n = {} states", poles.size(), n));
  std::vector<double> out;
  for (const auto& q : poles) {
    if (!q.is_negative())
      throw UserError(
          SourceLoc{},
          fmt::format("--thau-poles: pole {} is not in the open left half-plane", to_string(q)));
    out.push_back(q.to_double());
  }
  return out;
}

std::optional<GiNaC::matrix> chosen_Q(const DesignOptions& o, std::size_t n) {
  const auto q = real_list_option(o, "thau-q");
  if (q.empty()) return std::nullopt;
  GiNaC::matrix Q(static_cast<unsigned>(n), static_cast<unsigned>(n));
  if (q.size() == n) {
    for (std::size_t i = 0; i < n; ++i) Q(i, i) = q[i];
  } else if (q.size() == n * n) {
    for (std::size_t i = 0; i < n; ++i)
      for (std::size_t j = 0; j < n; ++j) Q(i, j) = q[i * n + j];
  } else {
    throw UserError(SourceLoc{}, fmt::format("--thau-q: expected {} diagonal entries or {} entries "
                                             "(row-major), got {}",
                                             n, n * n, q.size()));
  }
  const Eigen::MatrixXd E = to_eigen(Q);
  if (!E.isApprox(E.transpose(), 0)) throw UserError(SourceLoc{}, "--thau-q: Q must be symmetric");
  if (Eigen::LLT<Eigen::MatrixXd>(E).info() != Eigen::Success ||
      Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(E).eigenvalues()(0) <= 0)
    throw UserError(SourceLoc{}, "--thau-q: Q must be positive definite");
  return Q;
}

// Exact poles and L: the poles as given or rounded to 3 significant digits, L by exact
// Ackermann through the chosen output.
void exact_gain(const Split& s, const DesignOptions& o, const SearchOutcome& best, Result& r) {
  const std::size_t n = static_cast<std::size_t>(s.A.rows());
  if (r.user_poles)
    for (const auto& q : real_list_option(o, "thau-poles")) r.poles.push_back(q);
  else
    for (double p : best.poles) r.poles.push_back(round_rational(p, 3));
  GiNaC::matrix crow(1, static_cast<unsigned>(n));
  for (std::size_t j = 0; j < n; ++j) crow(0, j) = s.C(s.output, j);
  r.L = place_poles_exact(s.A, crow, r.poles);
}

// Q normalised to sigma_max 1 and rounded to 1e-6 (I if that loses definiteness).
GiNaC::matrix exact_Q(const Eigen::MatrixXd& Q, unsigned n) {
  // No candidate accepted (every one non-finite on stiff models): Q = I, judged as any other.
  if (Q.rows() != static_cast<Eigen::Index>(n) || Q.cols() != Q.rows() || !Q.allFinite())
    return GiNaC::ex_to<GiNaC::matrix>(GiNaC::unit_matrix(n));
  Eigen::MatrixXd Qd = Q;
  Qd /= Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(Qd).eigenvalues()(Qd.rows() - 1);
  GiNaC::matrix E(n, n);
  for (unsigned i = 0; i < n; ++i)
    for (unsigned j = i; j < n; ++j) {
      const numeric v =
          round_absolute(Qd(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)), 1e6);
      E(i, j) = v;
      E(j, i) = v;
    }
  if (Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(to_eigen(E)).eigenvalues()(0) <= 0)
    return GiNaC::ex_to<GiNaC::matrix>(GiNaC::unit_matrix(n));
  return E;
}

// P of (21) for A + L C and Q: exact for n <= 6, else numeric with its residual; then the
// ratio sigma_min(Q)/sigma_max(P).
void solve_P(const Split& s, Result& r) {
  const std::size_t n = static_cast<std::size_t>(s.A.rows());
  GiNaC::matrix AL = s.A;
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = 0; j < n; ++j) AL(i, j) = s.A(i, j) + r.L[i] * s.C(s.output, j);
  std::optional<GiNaC::matrix> P = n <= 6 ? solve_lyapunov_exact(AL, r.Q) : std::nullopt;
  Eigen::MatrixXd Pd;
  if (P) {
    r.P = *P;
    Pd = to_eigen(r.P);
    r.P_exact = true;
    r.lyapunov_residual = 0;
  } else {
    const auto Pn = solve_lyapunov(to_eigen(AL), to_eigen(r.Q));
    r.P_exact = false;
    Pd = Pn ? *Pn
            : Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(n));
    r.P = GiNaC::matrix(static_cast<unsigned>(n), static_cast<unsigned>(n));
    for (std::size_t i = 0; i < n; ++i)
      for (std::size_t j = 0; j < n; ++j)
        r.P(i, j) = exact_of_double(Pd(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)));
    const Eigen::MatrixXd ALd = to_eigen(AL);
    r.lyapunov_residual = (ALd.transpose() * Pd + Pd * ALd + 2 * to_eigen(r.Q)).norm();
  }
  const Eigen::VectorXd ep = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(Pd).eigenvalues();
  const Eigen::VectorXd eq =
      Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(to_eigen(r.Q)).eigenvalues();
  r.sigma_max_P = ep(ep.size() - 1);
  // With a numeric P, the residual E changes Q by at most ||E||_2 / 2 <= ||E||_F / 2; eigenvalues
  // in double: a relative 1e-12 safety on both.
  r.sigma_min_Q = eq(0) * (1 - 1e-12) - r.lyapunov_residual / 2;
  r.ratio = ep(0) > 0 ? r.sigma_min_Q / (r.sigma_max_P * (1 + 1e-12))
                      : -std::numeric_limits<double>::infinity();
}

// The budgeted region search (n > kExhaustiveStates): sampled M to choose, the enclosure to
// certify. When no enclosure within its budget proves what the samples say, the region keeps
// the sampled M (labelled sampled; the verdict is then "sampled only") and not_proven says why.
void find_region_budgeted(const Model& m, const Split& s, Result& r) {
  r.domain = budgeted_region_at(m, s, 1.0, false);
  bool proven = false;
  if (r.domain.M_sampled < r.ratio) {
    const Region d = budgeted_region_at(m, s, 1.0, true);
    if (d.M.kind == certify::BoundKind::rigorous && d.M.value < r.ratio) {
      r.domain = d;
      proven = true;
    } else {
      r.domain.M.method += fmt::format("; the enclosure's bound {:.6g} ({}: {}) did not prove it",
                                       d.M.value, certify::bound_kind_name(d.M.kind), d.M.method);
      r.not_proven = fmt::format("on the whole domain the enclosure gave M <= {:.6g} ({})",
                                 d.M.value, d.M.method);
    }
  } else {
    r.domain.M.method += " (a lower bound of M: it already refutes (26), no enclosure needed)";
  }
  r.region = r.domain;
  r.region_found = proven;
  double lo = 0;
  if (!proven && !r.whole_domain_only && r.ratio > 0) {
    const std::size_t count = bisection_samples(m);
    double hi = 1;
    for (int k = 0; k < kRegionBisections; ++k) {
      const double mid = (lo + hi) / 2;
      if (budgeted_region_at(m, s, mid, false, count).M_sampled < kRegionTarget * r.ratio)
        lo = mid;
      else
        hi = mid;
    }
    double scale = lo;
    for (int attempt = 0; scale > 0 && attempt < kRigorousAttempts; ++attempt, scale *= kShrink) {
      const Region t = budgeted_region_at(m, s, scale, true);
      if (t.M.kind == certify::BoundKind::rigorous && t.M.value < r.ratio) {
        r.region = t;
        r.region_found = proven = true;
        r.not_proven.clear();
        break;
      }
      r.not_proven = fmt::format(
          "the enclosure did not prove M < sigma_min(Q)/sigma_max(P) on the whole domain nor on "
          "{} sub-boxes (scale {:.6g} down to {:.6g}; last: M <= {:.6g}, {})",
          attempt + 1, lo, scale, t.M.value, t.M.method);
    }
  }
  if (!proven) {
    // Sampled only: the domain when the samples say (26) holds there, else the bisection's box.
    if (r.domain_margin() > 0) {
      r.region = r.domain;
      r.region_found = true;
    } else if (lo > 0) {
      r.region = budgeted_region_at(m, s, lo, false);
      r.region_found = r.margin() > 0;
    }
  }
  r.holds = r.region_found && r.margin() > 0;
  r.rigorous = r.region.M.kind == certify::BoundKind::rigorous;
}

// M on the declared domain, then (unless --thau-region domain) the largest sub-box around x*
// where (26) holds, by bisection of its scale.
void find_region(const Model& m, const Split& s, Result& r) {
  r.domain = region_at(m, s, 1.0, true);
  r.region = r.domain;
  r.region_found = r.domain_margin() > 0;
  if (!r.region_found && !r.whole_domain_only && r.ratio > 0) {
    double lo = 0, hi = 1;
    for (int k = 0; k < kRegionBisections; ++k) {
      const double mid = (lo + hi) / 2;
      const Region t = region_at(m, s, mid, false);
      if (t.M.value < kRegionTarget * r.ratio)
        lo = mid;
      else
        hi = mid;
    }
    if (lo > 0) {
      r.region = region_at(m, s, lo, true);
      r.region_found = r.margin() > 0;
    }
  }
  r.holds = r.region_found && r.margin() > 0;
  r.rigorous = r.region.M.kind == certify::BoundKind::rigorous;
}

Result design(const Model& m, const DesignOptions& o) {
  Result r;
  r.split = split_model(m);
  if (!r.split.not_applicable.empty()) return r;
  const Split& s = r.split;
  const std::size_t n = m.n();
  r.budgeted = n > kExhaustiveStates;
  const auto up = chosen_poles(o, n);
  const auto uQ = chosen_Q(o, n);
  r.user_poles = !up.empty();
  r.user_Q = uQ.has_value();
  r.whole_domain_only =
      choice_option(o, "thau-region", {"auto", "domain"}).value_or("auto") == "domain";

  const Eigen::MatrixXd A = to_eigen(s.A);
  Eigen::RowVectorXd c(static_cast<Eigen::Index>(n));
  for (std::size_t j = 0; j < n; ++j)
    c(static_cast<Eigen::Index>(j)) =
        to_eigen(s.C)(static_cast<Eigen::Index>(s.output), static_cast<Eigen::Index>(j));
  const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(A.rows(), A.cols());
  const SearchOutcome best = search(A, c, up,
                                    uQ           ? std::optional<Eigen::MatrixXd>(to_eigen(*uQ))
                                    : r.budgeted ? std::optional<Eigen::MatrixXd>(I)
                                                 : std::nullopt);
  r.choices_tried = best.tried;

  // Exact design: poles rounded to 3 significant digits, L by exact Ackermann, Q rounded to
  // 6 digits (or as given), P exact from (21).
  exact_gain(s, o, best, r);
  r.Q = uQ           ? *uQ
        : r.budgeted ? GiNaC::ex_to<GiNaC::matrix>(GiNaC::unit_matrix(static_cast<unsigned>(n)))
                     : exact_Q(best.Q, static_cast<unsigned>(n));
  solve_P(s, r);
  if (r.budgeted)
    find_region_budgeted(m, s, r);
  else
    find_region(m, s, r);
  return r;
}

std::string box_text(const Model& m, const certify::Box& b) {
  std::vector<std::string> out;
  for (std::size_t k = 0; k < b.vars.size(); ++k)
    for (const auto& x : m.states)
      if (b.vars[k].is_equal(x))
        out.push_back(
            fmt::format("{} in [{:.6g}, {:.6g}]", x.get_name(), b.ranges[k].lo, b.ranges[k].hi));
  return fmt::format("{}", fmt::join(out, ", "));
}

std::string bound_text(const certify::Bound& b) {
  return fmt::format("{:.6g} ({}: {})", b.value, certify::bound_kind_name(b.kind), b.method);
}

std::string numbers_text(const std::vector<numeric>& v) {
  std::vector<std::string> s;
  for (const auto& q : v) s.push_back(to_string(q));
  return fmt::format("{}", fmt::join(s, ", "));
}

std::vector<std::string> verdict_reasons(const Model& m, const Result& r) {
  if (!r.split.not_applicable.empty()) return {r.split.not_applicable};
  std::vector<std::string> out;
  const std::string cond =
      fmt::format("sigma_min(Q)/sigma_max(P) = {:.6g} (best of {} choices of poles and Q tried)",
                  r.ratio, r.choices_tried);
  if (r.domain_margin() > 0) {
    out.push_back(fmt::format(
        "condition (26) holds on the whole domain: {} > M = {}; margin {:.6g} ({} bound; the "
        "sampled estimate of M is {:.6g})",
        cond, bound_text(r.domain.M), r.domain_margin(), certify::bound_kind_name(r.domain.M.kind),
        r.domain.M_sampled));
  } else {
    out.push_back(fmt::format(
        "on the whole domain condition (26) fails: {} <= M = {}; margin {:.6g} (sampled M {:.6g})",
        cond, bound_text(r.domain.M), r.domain_margin(), r.domain.M_sampled));
    if (r.holds)
      out.push_back(fmt::format(
          "it holds locally on W = {} (the states phi's Jacobian depends on scaled by {:.6g} "
          "towards x*, the largest such box with M <= {} sigma_min(Q)/sigma_max(P)): M = {}, "
          "margin {:.6g} (sampled M {:.6g}); the error decays while x and xh stay in W",
          box_text(m, r.region.box), r.region.scale, kRegionTarget, bound_text(r.region.M),
          r.margin(), r.region.M_sampled));
    else if (r.whole_domain_only)
      out.push_back("no sub-box searched (--thau-region domain)");
    else
      out.push_back(fmt::format(
          "no sub-box around x* down to scale 2^-{} satisfies it either: no choice tried "
          "satisfies the condition, best margin {:.6g}",
          kRegionBisections, r.margin()));
  }
  if (r.holds && !r.rigorous)
    out.push_back(r.not_proven.empty()
                      ? "M is only a sampled estimate (the enclosure fell back to sampling): not "
                        "proven"
                      : "M is only a sampled estimate: not proven; " + r.not_proven);
  return out;
}

// A region below this scale (per state phi's Jacobian depends on) is too small to rely on.
constexpr double kUsefulRegionScale = 0.25;

// Share of the domain box's volume the certified region covers, and over how many states.
std::pair<double, std::size_t> region_share(const Model& m, const Result& r) {
  std::size_t k = 0;
  for (const auto& x : m.states) k += jacobian_depends_on(m, r.split, x) ? 1 : 0;
  return {std::pow(r.region.scale, static_cast<double>(k)), k};
}

Verdict verdict_of(const Analysis& a, const Lazy<Result>& work) {
  const Result& r = work.get();
  Verdict v;
  v.reasons = verdict_reasons(a.model, r);
  v.applies = r.holds && r.rigorous;
  if (!v.applies) return v;
  if (r.domain_margin() > 0) {
    v.guarantee = Guarantee::rigorous;
    v.guarantee_text = fmt::format(
        "condition (26) proved over the whole domain box (margin {:.6g}, Arb)", r.domain_margin());
    return v;
  }
  const auto [share, k] = region_share(a.model, r);
  const std::string where = fmt::format(
      "W = {}, {:.3g} % of the domain box's volume ({:.3g} of its width in {} state{})",
      box_text(a.model, r.region.box), 100 * share, r.region.scale, k, k == 1 ? "" : "s");
  if (r.region.scale < kUsefulRegionScale) {
    v.applies = false;
    v.reasons.push_back(
        fmt::format("the certified region is too small to rely on: {} (below {:g} of the width)",
                    where, kUsefulRegionScale));
    return v;
  }
  v.guarantee = Guarantee::partial;
  v.guarantee_text = "condition (26) proved (Arb) only on the sub-box " + where +
                     ": the error decays while x and xh stay in it";
  return v;
}

GeneratedFunction fn(const std::string& name, const std::string& doc, std::vector<FunctionArg> args,
                     ExVec out, const std::string& out_type = "State") {
  GeneratedFunction f;
  f.name = name;
  f.doc = doc;
  f.args = std::move(args);
  f.out_rows = out.size();
  f.outputs = std::move(out);
  f.out_type = out_type;
  return f;
}

std::vector<GiNaC::symbol> output_symbols(const Model& m) {
  return measurement_symbols(m);
}

std::vector<numeric> flat(const GiNaC::matrix& M) {
  std::vector<numeric> v;
  for (unsigned i = 0; i < M.rows(); ++i)
    for (unsigned j = 0; j < M.cols(); ++j) v.push_back(GiNaC::ex_to<numeric>(M(i, j)));
  return v;
}

// xh' = A xh + B u + phi(xh, u) + L (h(xh) - y)  (seed 001 eq. 19).
ExVec thau_rhs(const Model& m, const Split& s, const GiNaC::matrix& L,
               const std::vector<GiNaC::symbol>& y) {
  const std::size_t n = m.n(), p = m.p();
  ExVec rhs;
  for (std::size_t i = 0; i < n; ++i) {
    ex acc = 0;
    for (std::size_t j = 0; j < n; ++j) acc += s.A(i, j) * m.states[j];
    for (std::size_t j = 0; j < m.m(); ++j) acc += s.B(i, j) * m.inputs[j];
    acc += s.phi[i];
    for (std::size_t k = 0; k < p; ++k) acc += L(i, k) * (m.h[k] - y[k]);
    rhs.push_back(acc);
  }
  return rhs;
}

// The spec without its texts: the estimate is the state, integrated by the rhs.
ObserverSpec thau_skeleton(const Model& m, const Split& s, const GiNaC::matrix& L) {
  const auto y = output_symbols(m);
  const ExVec rhs = thau_rhs(m, s, L, y);
  ObserverSpec spec;
  spec.method = "thau";
  spec.class_suffix = "Thau";
  spec.state_size = m.n();
  spec.params = runtime_params(m);
  spec.functions = model_functions(m);
  spec.functions.push_back(fn("phi",
                              "Nonlinear part phi(x, u) = f + g - A x - B u of the exact split.",
                              {state_arg(m), input_arg(m)}, s.phi));
  spec.functions.push_back(fn("x_rhs",
                              "xh' = A xh + B u + phi(xh, u) + L (h(xh) - y)  (seed 001 eq. 19).",
                              {state_arg(m), input_arg(m), output_arg(y)}, rhs));
  spec.state_name = "xh";
  spec.state_doc = "the estimate itself";
  spec.init = InitKind::identity;
  spec.update = UpdateKind::ode;
  spec.roles.rhs = "x_rhs";
  spec.estimate = EstimateKind::identity;
  return spec;
}

// Title, description, class documentation and constants; W names the certified region.
void describe_thau(ObserverSpec& spec, const Result& r, const GiNaC::matrix& L,
                   const std::string& W) {
  spec.title = "Thau observer (Lipschitz nonlinearity, Lyapunov certificate)";
  spec.description = {
      "Observer: Thau (1973; seed 001 §4, eq. 18-26), x' = A x + B u + phi(x, u), y = C x",
      fmt::format("Poles of A + L C: {}; L = {}", numbers_text(r.poles), matrix_text(L)),
      fmt::format("Certificate (26): sigma_min(Q)/sigma_max(P) = {:.6g} > M = {:.6g} ({}) on {}",
                  r.ratio, r.region.M.value, certify::bound_kind_name(r.region.M.kind), W)};
  spec.class_doc = {"  xh' = A xh + B u + phi(xh, u) + L (h(xh) - y),  A + L C Hurwitz",
                    "(seed 001 eq. 19, L (yh - y)); V = e' P e decreases while x and xh stay in",
                    fmt::format("{}.", W)};
  spec.constants.push_back({"poles", r.poles, "eigenvalues of A + L C"});
  spec.constants.push_back({"L", flat(L), "output-injection gain, n x p row-major"});
  spec.constants.push_back({"A", flat(r.split.A), "linear part dF/dx at x*, row-major"});
  spec.constants.push_back({"Q", flat(r.Q), "Q of eq. (21), row-major"});
  spec.constants.push_back({"P", flat(r.P), "P of eq. (21), row-major"});
}

// The report rows and the summary.
void report_thau(ObserverSpec& spec, const Result& r, const GiNaC::matrix& L,
                 const std::string& W) {
  const Split& s = r.split;
  spec.report = {
      {"split",
       fmt::format("A = {}, B = {}, C = {} (Jacobians at x* = ({}), u* = ({})); phi = [{}]",
                   matrix_text(s.A), matrix_text(s.B), matrix_text(s.C), numbers_text(s.x_star),
                   numbers_text(s.u_star), fmt::join(to_strings(s.phi), ", "))},
      {"convention", "xh' = A xh + B u + phi + L (C xh - y) (seed eq. 19), A + L C Hurwitz"},
      {"poles",
       fmt::format("{} ({})", numbers_text(r.poles),
                   r.user_poles ? "given with --thau-poles"
                                : fmt::format("searched in [-{}, -{}] for the largest ratio",
                                              kMaxPole, kMinPole))},
      {"L", matrix_text(L)},
      {"Q",
       fmt::format("{} ({})", matrix_text(r.Q),
                   r.user_Q     ? "given with --thau-q"
                   : r.budgeted ? "I: no Q gives a larger sigma_min(Q)/sigma_max(P) for any L, "
                                  "since P_Q >= sigma_min(Q) P_I"
                                : "searched")},
      {"P", fmt::format("{} ({}; Lyapunov residual {:.3g})", matrix_text(to_eigen(r.P)),
                        r.P_exact ? "exact rational solution of (21)" : "numeric solution of (21)",
                        r.lyapunov_residual)},
      {"sigma_min(Q)/sigma_max(P)",
       fmt::format(
           "{:.6g} = {:.6g} / {:.6g} (equal to sigma_min(Q)/(2 sigma_max(P')) with "
           "A_L^T P' + P' A_L = -Q); eigenvalues of the exact P and Q in double with a 1e-12 "
           "relative safety; {} choices tried",
           r.ratio, r.sigma_min_Q, r.sigma_max_P, r.choices_tried)},
      {"M on the domain",
       fmt::format("{}; sampled estimate {:.6g}", bound_text(r.domain.M), r.domain.M_sampled)},
      {"region", W},
      {"M on the region",
       fmt::format("{}; sampled estimate {:.6g}", bound_text(r.region.M), r.region.M_sampled)},
      {"margin", fmt::format("{:.6g} ({})", r.margin(),
                             r.rigorous ? "M rigorous" : "M sampled: not proven")}};
  spec.summary = fmt::format(
      "Thau observer, poles {}, certificate sigma_min(Q)/sigma_max(P) = {:.6g} > M = {:.6g} on {} "
      "(margin {:.6g}, M {})",
      numbers_text(r.poles), r.ratio, r.region.M.value, W, r.margin(),
      certify::bound_kind_name(r.region.M.kind));
}

ObserverSpec build_from(const Analysis& a, const Result& r) {
  const Model& m = a.model;
  if (!r.split.not_applicable.empty() || !r.holds)
    throw UserError(SourceLoc{m.file, 0, 0},
                    "method 'thau' does not apply: " +
                        fmt::format("{}", fmt::join(verdict_reasons(m, r), "; ")));
  const std::size_t n = m.n(), p = m.p();
  // L as n x p: the chosen output's column, zeros elsewhere.
  GiNaC::matrix L(static_cast<unsigned>(n), static_cast<unsigned>(p));
  for (std::size_t i = 0; i < n; ++i) L(i, r.split.output) = r.L[i];
  ObserverSpec spec = thau_skeleton(m, r.split, L);
  const std::string W =
      r.region.scale == 1 ? "the whole domain" : "W = " + box_text(m, r.region.box);
  describe_thau(spec, r, L, W);
  report_thau(spec, r, L, W);
  return spec;
}

}  // namespace

ThauCertificate thau_certificate(const Model& m, const DesignOptions& o) {
  const Result r = design(m, o);
  ThauCertificate c;
  c.not_applicable = r.split.not_applicable;
  if (!c.not_applicable.empty()) return c;
  for (const auto& q : r.poles) c.poles.push_back(q.to_double());
  for (const auto& l : r.L) c.L.push_back(l.to_double());
  c.output = r.split.output;
  c.ratio = r.ratio;
  c.M_domain = r.domain.M.value;
  c.M_domain_sampled = r.domain.M_sampled;
  c.M_region = r.region.M.value;
  c.M_region_sampled = r.region.M_sampled;
  c.M_rigorous = r.rigorous;
  c.margin_domain = r.domain_margin();
  c.margin_region = r.margin();
  c.scale = r.region.scale;
  for (std::size_t k = 0; k < r.region.box.vars.size(); ++k)
    for (const auto& x : m.states)
      if (r.region.box.vars[k].is_equal(x))
        c.region.emplace_back(r.region.box.ranges[k].lo, r.region.box.ranges[k].hi);
  c.holds = r.holds;
  c.choices_tried = r.choices_tried;
  return c;
}

Design thau_design() {
  Design d;
  d.name = "thau";
  d.summary =
      "Thau observer: linear part + Lipschitz phi, Lyapunov certificate (seed 001 eq. 18-26)";
  d.options = {
      {"thau-poles", "Thau observer: poles of A + L C, comma-separated negative reals",
       "searched (best certificate)"},
      {"thau-q", "Thau observer: Q of eq. (21), n diagonal entries or n*n row-major", "searched"},
      {"thau-region", "Thau observer: auto (largest certified sub-box) or domain", "auto"}};
  d.plan = work_plan<Result, design, verdict_of, build_from>;
  d.verdict_searches = true;  // a search over gains with Arb bounds: seconds
  return d;
}

}  // namespace obsynth
