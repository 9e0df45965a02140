#include "certify/riccati_certificate.hpp"

#include <arb.h>
#include <fmt/format.h>

#include <Eigen/Dense>
#include <cmath>
#include <limits>

#include "foundation/diagnostics.hpp"

namespace obsynth::certify {

using GiNaC::ex;
using GiNaC::matrix;

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr slong kPrec = 96;

// RAII ball with the few operations the formulas need.
class Num {
 public:
  Num() { arb_init(v_); }
  explicit Num(double d) {
    arb_init(v_);
    arb_set_d(v_, d);
  }
  Num(const Num& o) {
    arb_init(v_);
    arb_set(v_, o.v_);
  }
  Num& operator=(const Num& o) {
    arb_set(v_, o.v_);
    return *this;
  }
  ~Num() { arb_clear(v_); }
  friend Num operator+(const Num& a, const Num& b) {
    Num r;
    arb_add(r.v_, a.v_, b.v_, kPrec);
    return r;
  }
  friend Num operator-(const Num& a, const Num& b) {
    Num r;
    arb_sub(r.v_, a.v_, b.v_, kPrec);
    return r;
  }
  friend Num operator*(const Num& a, const Num& b) {
    Num r;
    arb_mul(r.v_, a.v_, b.v_, kPrec);
    return r;
  }
  friend Num operator/(const Num& a, const Num& b) {
    Num r;
    arb_div(r.v_, a.v_, b.v_, kPrec);
    return r;
  }
  friend Num sqrt(const Num& a) {
    Num r;
    arb_sqrt(r.v_, a.v_, kPrec);
    return r;
  }
  friend Num exp(const Num& a) {
    Num r;
    arb_exp(r.v_, a.v_, kPrec);
    return r;
  }
  double upper() const {
    if (!arb_is_finite(v_)) return kInf;
    arf_t u;
    arf_init(u);
    arb_get_ubound_arf(u, v_, kPrec);
    const double d = arf_get_d(u, ARF_RND_CEIL);
    arf_clear(u);
    return d;
  }
  double lower() const {
    if (!arb_is_finite(v_)) return -kInf;
    arf_t u;
    arf_init(u);
    arb_get_lbound_arf(u, v_, kPrec);
    const double d = arf_get_d(u, ARF_RND_FLOOR);
    arf_clear(u);
    return d;
  }

 private:
  arb_t v_;
};

BoundKind worst(BoundKind a, BoundKind b) {
  return a == BoundKind::rigorous && b == BoundKind::rigorous ? BoundKind::rigorous
                                                              : BoundKind::sampled;
}

matrix identity(std::size_t n) {
  matrix I(static_cast<unsigned>(n), static_cast<unsigned>(n));
  for (unsigned i = 0; i < n; ++i) I(i, i) = 1;
  return I;
}

matrix jacobian(const ExVec& v, const std::vector<GiNaC::symbol>& x) {
  matrix J(static_cast<unsigned>(v.size()), static_cast<unsigned>(x.size()));
  for (std::size_t i = 0; i < v.size(); ++i)
    for (std::size_t j = 0; j < x.size(); ++j)
      J(static_cast<unsigned>(i), static_cast<unsigned>(j)) = v[i].diff(x[j]);
  return J;
}

// [Hess v_1; ...; Hess v_k] ((k n) x n) and whether it is identically zero.
matrix stacked_hessians(const ExVec& v, const std::vector<GiNaC::symbol>& x, bool& zero) {
  const auto n = static_cast<unsigned>(x.size());
  matrix K(static_cast<unsigned>(v.size()) * n, n);
  zero = true;
  for (std::size_t i = 0; i < v.size(); ++i)
    for (unsigned a = 0; a < n; ++a) {
      const ex da = v[i].diff(x[a]);
      for (unsigned b = 0; b < n; ++b) {
        const ex e = da.diff(x[b]);
        K(static_cast<unsigned>(i) * n + a, b) = e;
        if (!e.normal().is_zero()) zero = false;
      }
    }
  return K;
}

bool constant_matrix(const matrix& M) {
  for (unsigned i = 0; i < M.rows(); ++i)
    for (unsigned j = 0; j < M.cols(); ++j) {
      const ex e = M(i, j).evalf();
      if (!GiNaC::is_a<GiNaC::numeric>(e) || !GiNaC::ex_to<GiNaC::numeric>(e).is_real())
        return false;
    }
  return true;
}

// Value of a matrix at a box point, as doubles (GiNaC evalf; an oracle path independent of the
// ball evaluator, used for the sampled estimates).
Eigen::MatrixXd at_point(const matrix& M, const Box& box, const std::vector<double>& pt) {
  GiNaC::exmap sub;
  for (std::size_t k = 0; k < box.vars.size() && k < pt.size(); ++k)
    sub[box.vars[k]] = GiNaC::numeric(pt[k]);
  Eigen::MatrixXd out(M.rows(), M.cols());
  for (unsigned i = 0; i < M.rows(); ++i)
    for (unsigned j = 0; j < M.cols(); ++j) {
      const ex e = GiNaC::evalf(M(i, j).subs(sub));
      out(i, j) = GiNaC::is_a<GiNaC::numeric>(e) ? GiNaC::ex_to<GiNaC::numeric>(e).to_double()
                                                 : std::nan("");
    }
  return out;
}

double norm_at(const matrix& M, const Box& box, const std::vector<double>& pt) {
  if (M.rows() == 0 || M.cols() == 0) return 0;
  const Eigen::MatrixXd A = at_point(M, box, pt);
  return Eigen::JacobiSVD<Eigen::MatrixXd>(A).singularValues()(0);
}

// Rigorous lower bound of lambda_min of a constant symmetric matrix (via negative_definite of
// -M, whose eigenvalue bound is an upper bound of -lambda_min).
CertValue lambda_min_lower(const matrix& M, const Box& box, const EnclosureBudget& budget) {
  const DefinitenessVerdict v = negative_definite(matrix(M.mul_scalar(-1)), box, budget);
  return {-v.max_eigenvalue_bound, v.kind, ">="};
}

std::string num(double v) {
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  return fmt::format("{:.6g}", v);
}

std::string point_text(const Box& box, const std::vector<double>& pt) {
  std::string s;
  for (std::size_t k = 0; k < box.vars.size() && k < pt.size(); ++k)
    s += fmt::format("{}{} = {:.6g}", k ? ", " : "", box.vars[k].get_name(), pt[k]);
  return s;
}

std::string value_text(const CertValue& v) {
  return fmt::format("{} {} ({})", v.direction, num(v.value), bound_kind_name(v.kind));
}

std::string bound_text(const Bound& b) {
  return fmt::format("<= {} ({}; {})", num(b.value), bound_kind_name(b.kind), b.method);
}

// Lemma 3.1 / (3.8): p(sigma) as an upper bound, from upper bounds of ||A||, ||N||, ||H||,
// ||P0|| and a lower bound of r0.
Num p_of_sigma(double sigma, double A, double N, double H, double P0, double r0) {
  const Num s(sigma), a(A), n(N), h(H), p0(P0), r(r0), one(1.0), two(2.0), four(4.0);
  const Num e2 = exp(two * s * a);
  const Num beta0 = s / e2 / (one + s * s * e2 * n * n);
  const Num beta1 = s * exp(four * s * a) * (one + n * n / (r * s));
  const Num gamma = n * beta1;
  return beta0 / beta1 * p0 + (h * h + gamma * gamma) / (two * beta0);
}

// The parameters with their defaults (recorded in c.defaults_used); throws UserError for a
// wrong size or a non-constant Q0, N or R.
RiccatiParameters filled_parameters(const RiccatiParameters& params, unsigned n, unsigned p,
                                    const SourceLoc& where, RiccatiCertificate& c) {
  RiccatiParameters P = params;
  auto fill = [&](matrix& M, unsigned r, unsigned k, const char* name, const matrix& def,
                  const char* def_text) {
    if (M.rows() == 0 && M.cols() == 0) {
      M = def;
      c.defaults_used.push_back(fmt::format("{} = {}", name, def_text));
    } else if (M.rows() != r || M.cols() != k) {
      throw UserError(where, fmt::format("riccati: {} must be {} x {}, got {} x {}", name, r, k,
                                         M.rows(), M.cols()));
    }
  };
  fill(P.Q0, n, n, "Q0", identity(n), "I");
  fill(P.N, n, n, "N", identity(n), "I");
  fill(P.R, p, p, "R", identity(p), "I");
  fill(P.Lambda, n, p, "Lambda", matrix(n, p), "0");
  for (const auto& [name, M] :
       {std::pair<const char*, const matrix*>{"Q0", &P.Q0}, {"N", &P.N}, {"R", &P.R}})
    if (!constant_matrix(*M))
      throw UserError(where, fmt::format("riccati: {} must be a constant matrix", name));
  return P;
}

// The symbolic derivatives the bounds need: A = Df, Dh, R^-1, H = R^-1 Dh and the stacked
// Hessians of f and h.
struct Derivatives {
  matrix A, Dh, Rinv, H, D2f, D2h;
};

Derivatives derivatives(const Model& m, const RiccatiParameters& P, const SourceLoc& where,
                        RiccatiCertificate& c) {
  Derivatives d;
  const ExVec F = m.field();
  d.A = jacobian(F, m.states);
  d.Dh = jacobian(m.h, m.states);
  try {
    d.Rinv = P.R.inverse();
  } catch (const std::exception&) {
    throw UserError(where, "riccati: R must be invertible (R > 0)");
  }
  d.H = d.Rinv.mul(d.Dh);
  d.D2f = stacked_hessians(F, m.states, c.D2f_zero);
  d.D2h = stacked_hessians(m.h, m.states, c.D2h_zero);
  return d;
}

// Sup norms of the derivatives over the box, the norms and smallest eigenvalues of the
// constant design matrices; returns the lower bound of lambda_min((Q0 + Q0')/2).
CertValue bound_norms(const Derivatives& d, const RiccatiParameters& P,
                      const EnclosureBudget& budget, RiccatiCertificate& c) {
  c.Df = matrix_norm_bound(d.A, c.box, budget);
  c.Dh = matrix_norm_bound(d.Dh, c.box, budget);
  c.D2f = matrix_norm_bound(d.D2f, c.box, budget);
  c.D2h = matrix_norm_bound(d.D2h, c.box, budget);
  c.H = matrix_norm_bound(d.H, c.box, budget);
  c.Lambda = matrix_norm_bound(P.Lambda, c.box, budget);
  const Bound q0n = matrix_norm_bound(P.Q0, c.box, budget);
  const Bound nn = matrix_norm_bound(P.N, c.box, budget);
  const Bound rin = matrix_norm_bound(d.Rinv, c.box, budget);
  c.Q0_norm = {q0n.value, q0n.kind, "<="};
  c.N_norm = {nn.value, nn.kind, "<="};
  c.Rinv_norm = {rin.value, rin.kind, "<="};
  c.r0 = lambda_min_lower(P.N.mul(P.N.transpose()), c.box, budget);
  const matrix Rsym = (P.R.add(P.R.transpose())).mul_scalar(GiNaC::numeric(1, 2));
  c.R_min_eig = lambda_min_lower(Rsym, c.box, budget);
  const matrix Q0sym = (P.Q0.add(P.Q0.transpose())).mul_scalar(GiNaC::numeric(1, 2));
  const CertValue q0min = lambda_min_lower(Q0sym, c.box, budget);
  const Num lm(q0min.value);
  c.P0_norm = {q0min.value > 0 ? (Num(1.0) / lm).upper() : kInf, q0min.kind, "<="};
  c.P0_sqrt_norm = {q0min.value > 0 ? (Num(1.0) / sqrt(lm)).upper() : kInf, q0min.kind, "<="};
  return q0min;
}

// The standing assumptions of §2: Q0 > 0, rank N = n, R > 0; failures into c.
void standing_assumptions(const RiccatiParameters& P, const CertValue& q0min,
                          RiccatiCertificate& c) {
  if (!P.Q0.is_equal(P.Q0.transpose()) || !(q0min.value > 0))
    c.failures.push_back(
        fmt::format("Q0 > 0 (symmetric positive definite) fails: lambda_min(Q0) "
                    "bound {}",
                    num(q0min.value)));
  if (!(c.r0.value > 0))
    c.failures.push_back(
        fmt::format("rank N = n fails: lambda_min(N N') bound r0 = {}", num(c.r0.value)));
  if (!(c.R_min_eig.value > 0))
    c.failures.push_back(
        fmt::format("R > 0 fails: lambda_min((R + R')/2) bound {}", num(c.R_min_eig.value)));
}

// The largest eigenvalue of the symmetric part of S at the detectability test's worst point,
// in double (GiNaC + Eigen, independent of the enclosure); NaN when S is not finite there.
double largest_eigenvalue_at_worst(const matrix& S, const RiccatiCertificate& c) {
  Eigen::MatrixXd Sw = at_point(S, c.box, c.detectability.worst_point);
  Sw = (0.5 * (Sw + Sw.transpose())).eval();
  return Sw.allFinite() ? Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(Sw, Eigen::EigenvaluesOnly)
                              .eigenvalues()
                              .maxCoeff()
                        : std::nan("");
}

// (3.3) uniform detectability with the given Lambda: S = A + Lambda H negative definite on
// the box, alpha0 = -its largest eigenvalue; false (with the failure in c) when not shown.
bool detectability(const matrix& S, const EnclosureBudget& budget, RiccatiCertificate& c) {
  c.detectability = negative_definite(S, c.box, budget);
  c.alpha0 = {-c.detectability.max_eigenvalue_bound, c.detectability.kind, ">="};
  const bool detectable = c.detectability.holds && c.alpha0.value > 0;
  if (detectable) return true;
  const double lam = largest_eigenvalue_at_worst(S, c);
  if (c.detectability.kind == BoundKind::rigorous)
    c.failures.push_back(fmt::format(
        "uniform detectability (3.3) fails for the given Lambda (rigorous): at {} the symmetric "
        "part of A + Lambda H has largest eigenvalue {} >= 0 (eta' (A + Lambda H) eta >= 0 "
        "verified in ball arithmetic), so no alpha0 > 0 exists; it would need to be < 0",
        point_text(c.box, c.detectability.worst_point), num(lam)));
  else
    c.failures.push_back(fmt::format(
        "uniform detectability (3.3) is not established for the given Lambda (sampled): largest "
        "eigenvalue of the symmetric part of A + Lambda H found {} at {}; {}",
        num(lam), point_text(c.box, c.detectability.worst_point), c.detectability.method));
  return false;
}

// (3.8): p, minimised over sigma on a log grid (+inf when r0 is not positive).
void p_bound(BoundKind consts, RiccatiCertificate& c) {
  double best = kInf, best_sigma = 0;
  if (c.r0.value > 0)
    for (int k = 0; k <= 80; ++k) {
      const double sigma = std::pow(10.0, -4.0 + 6.0 * k / 80.0);
      const double v =
          p_of_sigma(sigma, c.Df.value, c.N_norm.value, c.H.value, c.P0_norm.value, c.r0.value)
              .upper();
      if (v < best) {
        best = v;
        best_sigma = sigma;
      }
    }
  c.p = {best, worst(worst(consts, c.Df.kind), c.H.kind), "<="};
  c.sigma = {best_sigma, BoundKind::rigorous, "="};
}

// (3.7) q as an upper bound, then (2.3) rho and (2.6) delta as lower bounds, in ball arithmetic.
void rho_and_delta(BoundKind consts, RiccatiCertificate& c) {
  const Num q = Num(c.Q0_norm.value) + (Num(c.N_norm.value) * Num(c.N_norm.value) +
                                        Num(c.Lambda.value) * Num(c.Lambda.value)) /
                                           (Num(2.0) * Num(c.alpha0.value));
  c.q = {q.upper(), worst(worst(consts, c.alpha0.kind), c.Lambda.kind), "<="};

  const Num qu(c.q.value), pu(c.p.value), r0(c.r0.value), ri(c.Rinv_norm.value);
  Num C(0.0);
  BoundKind rho_kind = worst(c.q.kind, c.P0_sqrt_norm.kind);
  if (!c.D2f_zero) {
    C = C + sqrt(pu) * Num(c.D2f.value);
    rho_kind = worst(rho_kind, worst(c.p.kind, c.D2f.kind));
  }
  if (!c.D2h_zero) {
    C = C + sqrt(qu) * ri * ri * Num(c.Dh.value) * Num(c.D2h.value);
    rho_kind = worst(rho_kind, worst(c.Dh.kind, c.D2h.kind));
  }
  if (c.D2f_zero && c.D2h_zero)
    c.rho = {kInf, rho_kind, ">="};
  else
    c.rho = {(r0 / (qu * qu * Num(c.P0_sqrt_norm.value)) / C).lower(), rho_kind, ">="};

  Num d = r0 / (qu * qu);
  BoundKind dk = c.q.kind;
  if (!c.D2f_zero) {
    d = d - Num(4.0) * pu * Num(c.Df.value);
    dk = worst(dk, worst(c.p.kind, c.Df.kind));
  }
  if (!c.D2h_zero) {
    d = d - Num(4.0) * ri * ri * Num(c.Dh.value) * Num(c.Dh.value);
    dk = worst(dk, c.Dh.kind);
  }
  c.delta = {d.lower(), dk, ">="};
}

// delta of (2.6) again with the sampled maxima (the values at the worst points found), in
// double: an estimate, for the report.
double sampled_delta(const Derivatives& dv, const RiccatiParameters& P, const matrix& S,
                     const RiccatiCertificate& c) {
  const double df_s = norm_at(dv.A, c.box, c.Df.worst_point);
  const double dh_s = norm_at(dv.Dh, c.box, c.Dh.worst_point);
  const double h_s = norm_at(dv.H, c.box, c.H.worst_point);
  const double lam_s = norm_at(P.Lambda, c.box, c.Lambda.worst_point);
  Eigen::MatrixXd Sw = at_point(S, c.box, c.detectability.worst_point);
  Sw = (0.5 * (Sw + Sw.transpose())).eval();
  const double alpha_s = -Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(Sw, Eigen::EigenvaluesOnly)
                              .eigenvalues()
                              .maxCoeff();
  const double nn2 = c.N_norm.value * c.N_norm.value;
  const double q_s = c.Q0_norm.value + (nn2 + lam_s * lam_s) / (2 * alpha_s);
  double p_s = kInf;
  for (int k = 0; k <= 80; ++k) {
    const double sigma = std::pow(10.0, -4.0 + 6.0 * k / 80.0);
    const double e2 = std::exp(2 * sigma * df_s);
    const double b0 = sigma / e2 / (1 + sigma * sigma * e2 * nn2);
    const double b1 = sigma * std::exp(4 * sigma * df_s) * (1 + nn2 / (c.r0.value * sigma));
    const double g = c.N_norm.value * b1;
    p_s = std::min(p_s, b0 / b1 * c.P0_norm.value + (h_s * h_s + g * g) / (2 * b0));
  }
  double ds = c.r0.value / (q_s * q_s);
  if (!c.D2f_zero) ds -= 4 * p_s * df_s;
  if (!c.D2h_zero) ds -= 4 * c.Rinv_norm.value * c.Rinv_norm.value * dh_s * dh_s;
  return ds;
}

// Which result applies (Theorem 2.1 locally, Corollary 2.1 globally), and the summary.
void conclude(RiccatiCertificate& c) {
  const bool standing = c.failures.empty();
  c.theorem_2_1 = standing && c.rho.value > 0;
  c.corollary_2_1 = standing && c.delta.value > 0;
  c.rigorous = c.detectability.kind == BoundKind::rigorous && c.delta.kind == BoundKind::rigorous &&
               c.rho.kind == BoundKind::rigorous;
  if (standing && !c.corollary_2_1)
    c.failures.push_back(fmt::format(
        "Corollary 2.1 needs delta > 0: delta {} {} (short by {}); with the sampled maxima "
        "delta ~ {}",
        c.delta.direction, num(c.delta.value), num(-c.delta.value), num(c.delta_sampled)));
  if (c.corollary_2_1)
    c.summary = fmt::format(
        "Corollary 2.1 applies (delta >= {}, {}): the James-Baras observer converges "
        "exponentially from every initial error, while plant and observer stay in the domain "
        "box",
        num(c.delta.value), c.rigorous ? "rigorous" : "sampled");
  else if (c.theorem_2_1)
    c.summary = fmt::format(
        "Theorem 2.1 applies with radius rho >= {} ({}): exponential convergence for |x0 - m0| "
        "< rho; Corollary 2.1 (global) does not",
        num(c.rho.value), c.rigorous ? "rigorous" : "sampled");
  else
    c.summary = "neither Theorem 2.1 nor Corollary 2.1 applies: " +
                (c.failures.empty() ? std::string("?") : c.failures.front());
}

}  // namespace

RiccatiCertificate riccati_certificate(const Model& m, const RiccatiParameters& params,
                                       const EnclosureBudget& budget) {
  RiccatiCertificate c;
  c.model = m.name;
  c.n_states = m.n();
  c.n_outputs = m.p();
  c.box = model_box(m);
  const SourceLoc where{m.file, 0, 0};
  const auto n = static_cast<unsigned>(c.n_states), p = static_cast<unsigned>(c.n_outputs);
  const RiccatiParameters P = filled_parameters(params, n, p, where, c);
  c.params = P;
  const Derivatives d = derivatives(m, P, where, c);
  const CertValue q0min = bound_norms(d, P, budget, c);
  standing_assumptions(P, q0min, c);
  const matrix S = d.A.add(P.Lambda.mul(d.H));
  const bool detectable = detectability(S, budget, c);

  const BoundKind consts = worst(worst(worst(c.Q0_norm.kind, c.N_norm.kind), c.r0.kind),
                                 worst(c.Rinv_norm.kind, c.P0_norm.kind));
  c.p_needed = !c.D2f_zero;
  c.rho = {0, BoundKind::rigorous, ">="};
  c.delta = {-kInf, BoundKind::rigorous, ">="};
  c.q = {kInf, BoundKind::rigorous, "<="};
  c.p = {kInf, BoundKind::rigorous, "<="};
  c.sigma = {0, BoundKind::rigorous, "="};
  p_bound(consts, c);
  if (detectable && c.alpha0.value > 0) {
    rho_and_delta(consts, c);
    c.delta_sampled = sampled_delta(d, P, S, c);
  } else {
    c.delta_sampled = std::nan("");
  }
  conclude(c);
  return c;
}

std::vector<ReportRow> riccati_certificate_rows(const RiccatiCertificate& c) {
  std::vector<ReportRow> rows;
  std::string box;
  for (std::size_t k = 0; k < c.box.vars.size(); ++k)
    box += fmt::format("{}{} in [{}, {}]", k ? ", " : "", c.box.vars[k].get_name(),
                       num(c.box.ranges[k].lo), num(c.box.ranges[k].hi));
  rows.push_back({"certificate scope", "sups over the domain box " + box +
                                           " (the paper takes them over R^n): the verdicts hold "
                                           "while plant and observer stay in the box"});
  if (!c.defaults_used.empty()) {
    std::string d;
    for (const auto& s : c.defaults_used) d += (d.empty() ? "" : ", ") + s;
    rows.push_back({"parameter defaults", d});
  }
  rows.push_back({"||Df|| = sup ||D_x(f+g)||", bound_text(c.Df)});
  rows.push_back(
      {"||D^2 f||", c.D2f_zero ? "0 (identically zero: terms omitted)" : bound_text(c.D2f)});
  rows.push_back({"||Dh||", bound_text(c.Dh)});
  rows.push_back(
      {"||D^2 h||", c.D2h_zero ? "0 (identically zero: terms omitted)" : bound_text(c.D2h)});
  rows.push_back({"||H|| = sup ||R^-1 Dh||", bound_text(c.H)});
  rows.push_back({"||Lambda||", bound_text(c.Lambda)});
  rows.push_back({"r0 = lambda_min(N N')", value_text(c.r0)});
  rows.push_back({"||Q0||", value_text(c.Q0_norm)});
  rows.push_back({"||P0|| = ||Q0^-1||", value_text(c.P0_norm)});
  rows.push_back({"||P0^(1/2)||", value_text(c.P0_sqrt_norm)});
  rows.push_back({"||N||", value_text(c.N_norm)});
  rows.push_back({"||R^-1||", value_text(c.Rinv_norm)});
  rows.push_back(
      {"uniform detectability (3.3)",
       fmt::format("{} ({}): largest eigenvalue of sym(A + Lambda H) {} {} over the box, worst "
                   "point {}; {}",
                   c.detectability.holds                         ? "holds"
                   : c.detectability.kind == BoundKind::rigorous ? "fails"
                                                                 : "not established",
                   bound_kind_name(c.detectability.kind),
                   c.detectability.kind == BoundKind::rigorous ? "<=" : "~",
                   num(c.detectability.max_eigenvalue_bound),
                   point_text(c.box, c.detectability.worst_point), c.detectability.method)});
  const bool detectable = c.detectability.holds && c.alpha0.value > 0;
  const std::string undefined = "undefined: (3.3) does not hold, so q of (3.7) is not bounded";
  rows.push_back({"alpha0", detectable ? value_text(c.alpha0) : undefined});
  rows.push_back({"q (3.7)", detectable ? value_text(c.q) : undefined});
  rows.push_back({"p (3.8)", fmt::format("{} at sigma = {}{}", value_text(c.p), num(c.sigma.value),
                                         c.p_needed ? "" : " (not needed: D^2 f = 0)")});
  if (!detectable) {
    rows.push_back({"rho (2.3)", undefined});
    rows.push_back({"delta (2.6)", undefined});
  } else {
    rows.push_back({"rho (2.3)", std::isinf(c.rho.value)
                                     ? fmt::format("infinite ({}): D^2 f = D^2 h = 0, no radius "
                                                   "condition",
                                                   bound_kind_name(c.rho.kind))
                                     : value_text(c.rho)});
    rows.push_back({"delta (2.6)", fmt::format("{}; with the sampled maxima ~ {}",
                                               value_text(c.delta), num(c.delta_sampled))});
  }
  rows.push_back({"Theorem 2.1 (local, |x0 - m0| < rho)",
                  !c.theorem_2_1            ? "does not apply"
                  : std::isinf(c.rho.value) ? "applies for every initial error"
                                            : fmt::format("applies, rho >= {}", num(c.rho.value))});
  rows.push_back({"Corollary 2.1 (global, delta > 0)",
                  c.corollary_2_1 ? fmt::format("applies, delta >= {}", num(c.delta.value))
                                  : "does not apply"});
  for (const auto& f : c.failures) rows.push_back({"failed condition", f});
  rows.push_back({"certificate", c.summary + (c.rigorous ? " [rigorous]" : " [sampled]")});
  return rows;
}

}  // namespace obsynth::certify
