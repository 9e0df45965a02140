#include "designs/high_gain.hpp"

#include <fmt/format.h>

#include <limits>
#include <optional>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "analysis/observability.hpp"
#include "analysis/triangular_form.hpp"
#include "certify/enclosure.hpp"
#include "designs/canonical.hpp"
#include "designs/options.hpp"
#include "front/fresh_names.hpp"
#include "symbolic/expr_print.hpp"
#include "symbolic/lie.hpp"
#include "symbolic/poly.hpp"
#include "symbolic/symbolic.hpp"
#include "symbolic/zero_test.hpp"

namespace obsynth {

using GiNaC::ex;
using GiNaC::numeric;

std::vector<numeric> high_gain_K(const std::vector<numeric>& poles) {
  const std::vector<numeric> c = gains_from_poles(poles);  // c_0 .. c_{n-1}
  const std::size_t n = poles.size();
  std::vector<numeric> K(n);
  for (std::size_t i = 0; i < n; ++i) K[i] = c[n - 1 - i];
  return K;
}

std::vector<numeric> high_gain_K(const std::vector<numeric>& poles,
                                 const std::vector<std::size_t>& blocks) {
  std::vector<numeric> K;
  auto first = poles.begin();
  for (const std::size_t k : blocks) {
    const auto block = high_gain_K(std::vector<numeric>(first, first + static_cast<long>(k)));
    K.insert(K.end(), block.begin(), block.end());
    first += static_cast<long>(k);
  }
  return K;
}

namespace {

// Why the indices cannot give block coordinates, or nothing.
std::optional<std::string> blocks_problem(const std::vector<std::size_t>& k, std::size_t n,
                                          std::size_t p) {
  if (k.size() != p)
    return fmt::format("the observability indices are not available for the {} outputs", p);
  std::size_t sum = 0;
  for (std::size_t i = 0; i < p; ++i) {
    if (k[i] == 0)
      return fmt::format(
          "output {} has observability index 0 (it adds no coordinate to the others): the "
          "block form needs every index >= 1 (drop that output)",
          i + 1);
    sum += k[i];
  }
  if (sum != n)
    return fmt::format("the observability indices sum to {} < n = {} (generic rank deficient)", sum,
                       n);
  return std::nullopt;
}

std::string indices_text(const std::vector<std::size_t>& k) {
  return fmt::format("({})", fmt::join(k, ", "));
}

}  // namespace

std::string high_gain_coordinates(const std::vector<std::size_t>& blocks) {
  if (blocks.size() <= 1) return "z = (h, L_f h, ..., L_f^{n-1} h)";
  return fmt::format(
      "z = (h_1, ..., L_f^{{k_1-1}} h_1, ..., h_p, ..., L_f^{{k_p-1}} h_p), indices (k_1, ..., "
      "k_p) = {}",
      indices_text(blocks));
}

HighGainStructure high_gain_structure(const Model& m, std::vector<std::size_t> indices) {
  HighGainStructure s;
  const std::size_t n = m.n(), p = m.p();
  if (indices.empty() && p == 1) indices = {n};
  if (const auto why = blocks_problem(indices, n, p)) {
    s.failures.push_back(*why);
    return s;
  }
  s.blocks = indices;
  // Per output: its chain h_i, ..., L_f^{k_i-1} h_i, and L_f^{k_i} h_i for the block's last row.
  ExVec tops;
  for (std::size_t i = 0; i < p; ++i) {
    const LieChain chain = lie_chain_with_gradients(m.h[i], m.f, m.states, indices[i] + 1);
    const auto k = static_cast<long>(indices[i]);
    s.Phi.insert(s.Phi.end(), chain.derivatives.begin(), chain.derivatives.begin() + k);
    s.O.insert(s.O.end(), chain.gradients.begin(), chain.gradients.begin() + k);
    tops.push_back(chain.derivatives[indices[i]]);
  }
  GiNaC::matrix O(static_cast<unsigned>(n), static_cast<unsigned>(n));
  for (std::size_t r = 0; r < n; ++r)
    for (std::size_t c = 0; c < n; ++c)
      O(static_cast<unsigned>(r), static_cast<unsigned>(c)) = s.O[r][c];
  s.det = GiNaC::normal(O.determinant(GiNaC::determinant_algo::laplace));
  const SampleBoxes boxes = m.sample_boxes();
  if (is_zero_verdict(zero_test(s.det, boxes))) {
    s.failures.push_back(
        p == 1 ? "det O = 0 identically: (h, L_f h, ..., L_f^{n-1} h) are not coordinates (the "
                 "drift alone does not make the system observable)"
               : "det O = 0 identically: " + high_gain_coordinates(indices) +
                     " are not coordinates (the drift alone does not make the system observable "
                     "with these indices)");
    return s;
  }
  // phi in x: z_{i,j}' = z_{i,j+1} + L_g L_f^{j-1} h_i, z_{i,k_i}' = L_f^{k_i} h_i + L_g
  // L_f^{k_i-1} h_i.
  for (std::size_t r = 0; r < n; ++r) {
    ex Lg = 0;
    for (std::size_t k = 0; k < n; ++k) Lg += s.O[r][k] * m.g[k];
    const std::size_t i = block_of(indices, r);
    const bool last = level_of(indices, r) == indices[i];
    s.phi.push_back(simplify(last ? tops[i] + Lg : Lg));
  }
  const GiNaC::matrix Oinv = O.inverse(GiNaC::solve_algo::gauss);
  const ExMatrix Dphi = jacobian(s.phi, m.states);
  s.J.assign(n, ExVec(n, 0));
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = 0; j < n; ++j) {
      ex acc = 0;
      for (std::size_t k = 0; k < n; ++k)
        acc += Dphi[i][k] * Oinv(static_cast<unsigned>(k), static_cast<unsigned>(j));
      s.J[i][j] = GiNaC::normal(acc);
    }
  // The structural condition of the header: d phi_r / d z_c = 0 where c's level exceeds r's.
  std::vector<std::string> bad;
  for (std::size_t r = 0; r < n; ++r)
    for (std::size_t c = 0; c < n; ++c)
      if (level_of(indices, c) > level_of(indices, r) &&
          !is_zero_verdict(zero_test(GiNaC::numer(s.J[r][c]), boxes)))
        bad.push_back(fmt::format("d phi_{}/d z_{} = {}", z_label(indices, r), z_label(indices, c),
                                  to_string(s.J[r][c])));
  if (bad.empty()) return s;
  if (p == 1)
    s.failures.push_back(fmt::format(
        "not uniformly observable in the form z' = A z + phi(z, u) with phi triangular, z = (h, "
        "L_f h, ...): {}",
        fmt::join(bad, "; ")));
  else
    s.failures.push_back(fmt::format(
        "not in the block-triangular form z' = A z + phi(z, u) with phi_{{i,j}} depending on "
        "z_{{l,1}}..z_{{l,j}} of every block l only, {}: {} (z_{{l,m}} with m > j)",
        high_gain_coordinates(indices), fmt::join(bad, "; ")));
  return s;
}

namespace {

std::string numbers_text(const std::vector<numeric>& v) {
  std::vector<std::string> s;
  for (const auto& q : v) s.push_back(to_string(q));
  return fmt::format("{}", fmt::join(s, ", "));
}

// --poles: n poles, split consecutively by the blocks; default: each block's default poles.
std::vector<numeric> chosen_poles(const DesignOptions& o, const std::vector<std::size_t>& blocks) {
  std::size_t n = 0;
  for (const std::size_t k : blocks) n += k;
  std::vector<numeric> poles = real_list_option(o, "poles");
  if (poles.empty()) {
    for (const std::size_t k : blocks) {
      const auto d = default_poles(k);
      poles.insert(poles.end(), d.begin(), d.end());
    }
    return poles;
  }
  if (poles.size() != n)
    throw UserError(SourceLoc{}, fmt::format("--poles: {} poles given, the model has n = {} states",
                                             poles.size(), n));
  for (const auto& q : poles)
    if (!q.is_negative())
      throw UserError(
          SourceLoc{},
          fmt::format("--poles: pole {} is not in the open left half-plane", to_string(q)));
  return poles;
}

// Default theta: the certificate's theta* with a margin, never below the floor (a useful speed
// when theta* = 1), never above the cap (the gain grows as theta^n and the fastest error pole,
// theta max|pole|, sets the largest step).
constexpr double kThetaFloor = 5, kThetaMargin = 1.25, kThetaCap = 200;

// 1.25 theta* rounded up to two significant digits, within [floor, cap].
numeric automatic_theta(double theta_star) {
  const double want = std::max(kThetaFloor, kThetaMargin * theta_star);
  if (!std::isfinite(want) || want >= kThetaCap) return numeric(static_cast<long>(kThetaCap));
  const double unit = std::pow(10.0, std::floor(std::log10(want)) - 1);
  const long digits = static_cast<long>(std::ceil(want / unit - 1e-9));
  return unit >= 1 ? numeric(digits * static_cast<long>(unit))
                   : numeric(digits, static_cast<long>(std::llround(1 / unit)));
}

std::optional<numeric> user_theta(const DesignOptions& o) {
  const auto t = real_option(o, "theta");
  if (!t) return std::nullopt;
  if (!t->is_positive())
    throw UserError(SourceLoc{}, fmt::format("--theta: {} is not positive", to_string(*t)));
  return *t;
}

// RK4's stability interval on the negative real axis is [-2.785, 0]: a step needs
// dt max|error pole| below it, the error poles being theta times the poles of A - K C.
double rk4_safe_period(const numeric& theta, const std::vector<numeric>& poles) {
  double fastest = 0;
  for (const auto& q : poles) fastest = std::max(fastest, std::abs(q.to_double()));
  return 2.785 / (theta.to_double() * fastest);
}

// lambda_max of P with (A - K C)^T P + P (A - K C) = -I (A upper shift, C = e_1).
double lyapunov_lambda_max(const std::vector<numeric>& K) {
  const auto n = static_cast<Eigen::Index>(K.size());
  Eigen::MatrixXd Acl = Eigen::MatrixXd::Zero(n, n);
  for (Eigen::Index i = 0; i + 1 < n; ++i) Acl(i, i + 1) = 1;
  for (Eigen::Index i = 0; i < n; ++i) Acl(i, 0) -= K[static_cast<std::size_t>(i)].to_double();
  const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(n, n);
  // vec(Acl^T P + P Acl) = (I (x) Acl^T + Acl^T (x) I) vec(P)
  Eigen::MatrixXd L = Eigen::MatrixXd::Zero(n * n, n * n);
  for (Eigen::Index i = 0; i < n; ++i)
    for (Eigen::Index j = 0; j < n; ++j) {
      L.block(i * n, j * n, n, n) += I(i, j) * Acl.transpose();
      L.block(i * n, j * n, n, n) += Acl(j, i) * I;
    }
  Eigen::VectorXd rhs = -Eigen::Map<const Eigen::VectorXd>(I.data(), n * n);
  const Eigen::VectorXd p = L.fullPivLu().solve(rhs);
  Eigen::MatrixXd P = Eigen::Map<const Eigen::MatrixXd>(p.data(), n, n);
  P = (P + P.transpose()) / 2;
  return Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(P).eigenvalues().maxCoeff();
}

// The same for A - K C block diagonal: P is block diagonal, its largest eigenvalue the blocks'.
double lyapunov_lambda_max(const std::vector<numeric>& K, const std::vector<std::size_t>& blocks) {
  double out = 0;
  auto first = K.begin();
  for (const std::size_t k : blocks) {
    out = std::max(out,
                   lyapunov_lambda_max(std::vector<numeric>(first, first + static_cast<long>(k))));
    first += static_cast<long>(k);
  }
  return out;
}

// sup over the model's domain box (states, inputs, free parameters) of |e|: certify's Arb
// enclosure (rigorous), or its sampled fallback (labelled so) where Arb cannot bound e.
struct EntryBound {
  double value = 0;
  bool rigorous = false;
  std::string method;
};

// Ball operations one entry's branch and bound may spend: an early stop leaves the bound
// rigorous, only looser (large entries: an 8-state model took minutes without it).
constexpr std::size_t kEntryWork = std::size_t{1} << 21;

EntryBound sup_abs_over_domain(const ex& e, const Model& m) {
  certify::EnclosureBudget budget;
  budget.max_work = kEntryWork;
  const certify::Bound b = certify::sup_abs(e, certify::model_box(m), budget);
  return {b.value, b.kind == certify::BoundKind::rigorous,
          fmt::format("{}, {}", certify::bound_kind_name(b.kind), b.method)};
}

// 6 significant digits rounded up: never below v (the bounds are upper bounds), and
// deterministic although the last bits of an Arb bound depend on GiNaC's term order.
std::string up6(double v) {
  if (!(v > 0) || !std::isfinite(v)) return fmt::format("{:g}", v);
  const double unit = std::pow(10.0, std::floor(std::log10(v)) - 5);
  return fmt::format("{:.6g}", std::ceil(v * (1 + 1e-12) / unit) * unit);
}

struct Certificate {
  double L = 0;            // Lipschitz constant of phi in z (spectral norm of entry bounds)
  bool rigorous = true;    // every entry bound rigorous
  bool unbounded = false;  // some entry has no finite bound: no theta guarantees convergence
  double lambda_P = 0;     // lambda_max(P)
  double theta_star = 0;   // max(1, 2 lambda_P L)
  std::vector<std::string> entries;  // "|d phi_i/d z_j| <= b (kind)"
};

Certificate certify(const Model& m, const HighGainStructure& st, const std::vector<numeric>& K) {
  Certificate c;
  const std::size_t n = m.n();
  Eigen::MatrixXd M =
      Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(n));
  const auto& B = st.blocks;
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = 0; j < n; ++j) {
      if (level_of(B, j) > level_of(B, i) || GiNaC::is_zero(st.J[i][j])) continue;
      const EntryBound b = sup_abs_over_domain(st.J[i][j], m);
      if (!std::isfinite(b.value)) {  // a pole in the box, or undefined at every sample
        c.unbounded = true;
        c.rigorous = false;
        c.entries.push_back(fmt::format("d phi_{}/d z_{} has no finite bound on the domain ({})",
                                        z_label(B, i), z_label(B, j), b.method));
        continue;
      }
      M(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)) = b.value;
      c.rigorous = c.rigorous && b.rigorous;
      c.entries.push_back(fmt::format("sup abs(d phi_{}/d z_{}) <= {} ({})", z_label(B, i),
                                      z_label(B, j), up6(b.value), b.method));
    }
  // L and lambda_max(P) are computed in double from the (rigorous) entry bounds and the exact K;
  // both are rounded up by a relative 1e-9, far above the rounding of these small problems.
  if (c.unbounded) {
    c.L = c.theta_star = std::numeric_limits<double>::infinity();
    c.lambda_P = (1 + 1e-9) * lyapunov_lambda_max(K, st.blocks);
    return c;
  }
  const double up = 1 + 1e-9;
  c.L = up * (M.norm() > 0 ? Eigen::JacobiSVD<Eigen::MatrixXd>(M).singularValues()(0) : 0.0);
  c.lambda_P = up * lyapunov_lambda_max(K, st.blocks);
  c.theta_star = std::max(1.0, 2 * c.lambda_P * c.L);
  return c;
}

// Where det O vanishes: its x-dependent factors, and whether each meets the domain box.
std::string singular_set(const Model& m, const HighGainStructure& st) {
  const ExVec factors = dependent_factors(st.det, m.states);
  if (factors.empty()) return fmt::format("never (det O = {})", to_string(st.det));
  std::vector<std::string> parts;
  const SampleBoxes boxes = m.sample_boxes();
  for (const auto& f : factors) {
    bool pos = false, neg = false, zero = false;
    for (const auto& pt : sample_points(m.all_symbols(), boxes, 256, 0x51c9)) {
      numeric v;
      if (!evaluate_real(f, pt, 20, v)) continue;
      if (v.is_zero())
        zero = true;
      else if (v.is_positive())
        pos = true;
      else
        neg = true;
    }
    parts.push_back(fmt::format("{} = 0 ({})", to_string(f),
                                (pos && neg) || zero ? "crosses the domain box (sampled)"
                                                     : "no sign change sampled in the domain box"));
  }
  return fmt::format("where {}", fmt::join(parts, "; "));
}

using NumericRows = std::vector<std::vector<numeric>>;

// At one sampled point: O, and the gradient of each phi_i = dL_f^{i-1} h . g, i < n (an empty
// row where phi_i is zero). Nothing where some entry does not evaluate.
struct PhiAtPoint {
  NumericRows O, dphi;
};

ex phi_expression(const Model& m, const Observability& ob, std::size_t i) {
  ex phi = 0;
  for (std::size_t k = 0; k < m.n(); ++k) phi += ob.O[i][k] * m.g[k];
  return phi;
}

// GiNaC: gradients of the expressions, evaluated at 40 digits.
std::vector<std::optional<PhiAtPoint>> sample_phi_ginac(const Model& m, const Observability& ob,
                                                        const std::vector<GiNaC::exmap>& points) {
  const std::size_t n = m.n();
  std::vector<ExVec> grads(n - 1);
  for (std::size_t i = 0; i + 1 < n; ++i) {
    const ex phi = phi_expression(m, ob, i);
    if (!phi.is_zero()) grads[i] = gradient(phi, m.states);
  }
  std::vector<std::optional<PhiAtPoint>> out;
  for (const auto& pt : points) {
    PhiAtPoint v{NumericRows(n), NumericRows(n - 1)};
    bool ok = true;
    auto eval = [&](const ex& e, std::vector<numeric>& row) {
      numeric val;
      ok = ok && evaluate_real(e, pt, 40, val);
      row.push_back(val);
    };
    for (std::size_t r = 0; r < n; ++r)
      for (std::size_t c = 0; c < n; ++c) eval(ob.O[r][c], v.O[r]);
    for (std::size_t i = 0; i + 1 < n; ++i)
      for (const auto& e : grads[i]) eval(e, v.dphi[i]);
    out.push_back(ok ? std::optional<PhiAtPoint>(std::move(v)) : std::nullopt);
  }
  return out;
}

const numeric kCancelled = numeric(1, 1000000) * numeric(10).power(-24);  // 1e-30

// The same in the polynomial ring when O and g live in it: no GiNaC gradients of large trees
// (nested family at n = 16: most of `check`'s time).
std::optional<std::vector<std::optional<PhiAtPoint>>> sample_phi_ring(
    const Model& m, const Observability& ob, const std::vector<GiNaC::exmap>& points) {
  const std::size_t n = m.n();
  // O's rows in the Lie chain's ring when the analysis kept them (else converted here), g in a
  // ring of its own: both are only evaluated at the same points.
  std::optional<PolyRing> own_O;
  const PolyRing* ring = nullptr;
  std::vector<std::vector<Poly>> O(n);
  if (ob.ring) {
    ring = &ob.ring->ring;
    O = ob.ring->rows;
  } else {
    std::vector<ex> all;
    for (const auto& row : ob.O) all.insert(all.end(), row.begin(), row.end());
    own_O = PolyRing::for_expressions(all, m.states);
    if (!own_O) return std::nullopt;
    ring = &*own_O;
    for (std::size_t r = 0; r < n; ++r)
      for (const auto& e : ob.O[r]) O[r].push_back(*ring->from_ex(e));
  }
  const auto g_ring = PolyRing::for_expressions(std::vector<ex>(m.g.begin(), m.g.end()), m.states);
  if (!g_ring) return std::nullopt;
  std::vector<Poly> g;
  for (const auto& e : m.g) g.push_back(*g_ring->from_ex(e));
  // d phi_i / dx_k = sum_j (dO_ij/dx_k g_j + O_ij dg_j/dx_k), with dO_ij/dx_k = dO_ik/dx_j (a
  // Hessian of L_f^i h): values at the points, never the product polynomials O_ij g_j (which
  // swell on dense models).
  std::vector<std::vector<std::vector<Poly>>> dO(n - 1, std::vector<std::vector<Poly>>(n));
  for (std::size_t i = 0; i + 1 < n; ++i)
    for (std::size_t j = 0; j < n; ++j)
      for (std::size_t k = j; k < n; ++k) dO[i][j].push_back(ring->derivative(O[i][j], k));
  std::vector<std::vector<Poly>> dg(n);
  for (std::size_t j = 0; j < n; ++j)
    for (std::size_t k = 0; k < n; ++k) dg[j].push_back(g_ring->derivative(g[j], k));
  const auto hessian = [&](std::size_t i, std::size_t j, std::size_t k) -> const Poly& {
    return j <= k ? dO[i][j][k - j] : dO[i][k][j - k];
  };
  std::vector<std::optional<PhiAtPoint>> out;
  for (const auto& pt : points) {
    const auto values = ring->values_at(pt, 40);
    const auto g_values = g_ring->values_at(pt, 40);
    if (!values || !g_values) {
      out.push_back(std::nullopt);
      continue;
    }
    DigitsGuard guard(40);
    const auto at = [&](const Poly& p) { return PolyRing::evaluate(p, *values); };
    const auto at_g = [&](const Poly& p) { return PolyRing::evaluate(p, *g_values); };
    PhiAtPoint v{NumericRows(n), NumericRows(n - 1)};
    for (std::size_t r = 0; r < n; ++r)
      for (const auto& p : O[r]) v.O[r].push_back(at(p));
    std::vector<numeric> g_at;
    for (const auto& p : g) g_at.push_back(at_g(p));
    for (std::size_t i = 0; i + 1 < n; ++i)
      for (std::size_t k = 0; k < n; ++k) {
        numeric d = 0, size = 0;
        for (std::size_t j = 0; j < n; ++j) {
          const numeric a = at(hessian(i, j, k)) * g_at[j], b = v.O[i][j] * at_g(dg[j][k]);
          d += a + b;
          size += GiNaC::abs(a) + GiNaC::abs(b);
        }
        // A sum that cancels to 40-digit rounding is zero (phi_i = 0 identically, say): the
        // rank test scales rows to unit norm, so a rounding residue must not survive.
        v.dphi[i].push_back(GiNaC::abs(d) <= size * kCancelled ? numeric(0) : d);
      }
    out.push_back(std::move(v));
  }
  return out;
}

// Whether some phi_i = dL_f^{i-1} h . g (i < n) depends on z_{i+1}..z_n, i.e. rank [dz_1; ...;
// dz_i; dphi_i] > i at a sampled point: the reason, or nothing when phi is triangular.
std::optional<std::string> phi_not_triangular(const Model& m, const Observability& ob) {
  const std::size_t n = m.n();
  const SampleBoxes boxes = m.sample_boxes();
  const auto points = sample_points(m.all_symbols(), boxes, 3, 0x4a11);
  auto sampled = sample_phi_ring(m, ob, points);
  if (!sampled) sampled = sample_phi_ginac(m, ob, points);
  for (std::size_t i = 0; i + 1 < n; ++i) {
    std::size_t rank = 0;
    for (const auto& at : *sampled) {
      if (!at || at->dphi[i].empty()) continue;
      NumericRows rows(at->O.begin(), at->O.begin() + static_cast<std::ptrdiff_t>(i) + 1);
      rows.push_back(at->dphi[i]);
      rank = std::max(rank, numeric_rank(rows, false));
    }
    if (rank > i + 1)
      return fmt::format(
          "not uniformly observable in the form z' = A z + phi(z, u) with phi triangular, z = "
          "(h, L_f h, ...): phi_{} = L_g L_f^{} h = {} depends on z_{}..z_n",
          i + 1, i, to_string(phi_expression(m, ob, i)), i + 2);
  }
  return std::nullopt;
}

// Cheap decision for `check` and `--method auto` (the symbolic J is left to build()): the
// analysis' O (rows dL_f^k h) must have generic rank n, and phi_i = dL_f^{i-1} h . g (i < n) must
// depend on z_1..z_i only, i.e. rank [dz_1; ...; dz_i; dphi_i] = i, decided by the rank at
// sampled points (numeric elimination at 40 digits).
// p > 1: the block structure computed symbolically with the analysis' indices (the sampled
// shortcut above is single-output); the verdict names every entry breaking the condition.
Verdict applies_blocks(const Analysis& a) {
  Verdict v;
  const Model& m = a.model;
  const Observability& ob = a.observability;
  if (!a.completed("observability") || ob.indices.size() != m.p()) {
    v.reasons.push_back("undecided: the observability indices are not available");
    return v;
  }
  if (ob.generic_rank < m.n()) {
    v.reasons.push_back(fmt::format(
        "generic rank {} < n = {}: the Lie derivatives of the outputs along the drift are not "
        "coordinates (the drift alone does not make the system observable)",
        ob.generic_rank, m.n()));
    return v;
  }
  const HighGainStructure st = high_gain_structure(m, ob.indices);
  if (!st.failures.empty()) {
    v.reasons = st.failures;
    return v;
  }
  v.applies = true;
  v.reasons.push_back(
      fmt::format("uniformly observable: in {} the model is z' = A z + phi(z, u) with phi block "
                  "triangular (phi_{{i,j}} depends on z_{{l,1}}..z_{{l,j}} of every block l only)",
                  high_gain_coordinates(st.blocks)));
  return v;
}

Verdict applies(const Analysis& a) {
  Verdict v;
  const Model& m = a.model;
  const std::size_t n = m.n();
  if (m.p() != 1) return applies_blocks(a);
  const Observability& ob = a.observability;
  if (!a.completed("observability") || ob.O.size() != n) {
    v.reasons.push_back("undecided: the symbolic observability matrix is not available (" +
                        (ob.symbolic_skipped.empty() ? std::string("observability stage incomplete")
                                                     : ob.symbolic_skipped) +
                        ")");
    return v;
  }
  if (ob.generic_rank < n) {
    v.reasons.push_back(fmt::format(
        "det O = 0 identically: (h, L_f h, ..., L_f^{{n-1}} h) are not coordinates (generic rank "
        "{} < n = {}; the drift alone does not make the system observable)",
        ob.generic_rank, n));
    return v;
  }
  bool g_zero = true;
  for (const auto& e : m.g) g_zero = g_zero && e.is_zero();
  if (!g_zero) {
    if (auto reason = phi_not_triangular(m, ob)) {
      v.reasons.push_back(*reason);
      return v;
    }
  }
  v.applies = true;
  v.reasons.push_back(
      "uniformly observable: in z = (h, L_f h, ..., L_f^{n-1} h) the model is z' = A z + "
      "phi(z, u) with phi triangular");
  return v;
}

GeneratedFunction fn(const std::string& name, const std::string& doc, std::vector<FunctionArg> args,
                     ExVec out, std::size_t cols, const std::string& out_type) {
  GeneratedFunction f;
  f.name = name;
  f.doc = doc;
  f.args = std::move(args);
  f.out_rows = out.size() / cols;
  f.out_cols = cols;
  f.outputs = std::move(out);
  f.out_type = out_type;
  return f;
}

// The gain chosen: poles of A - K C, K, theta and the gain Delta_theta K applied.
struct GainChoice {
  std::vector<numeric> poles, K;
  numeric theta;
  bool theta_given = false;
  std::vector<numeric> gain;  // Delta_theta K
};

// theta: --theta, else from the certificate's theta* (automatic_theta).
// Per block: K_i from its poles, and theta^j on the block's level j.
GainChoice choose_gain(const DesignOptions& o, std::vector<numeric> poles, double theta_star,
                       const std::vector<std::size_t>& blocks) {
  const std::size_t n = poles.size();
  GainChoice g;
  g.poles = std::move(poles);
  g.K = high_gain_K(g.poles, blocks);
  const auto given = user_theta(o);
  g.theta_given = given.has_value();
  g.theta = given ? *given : automatic_theta(theta_star);
  for (std::size_t r = 0; r < n; ++r)
    g.gain.push_back(g.theta.power(numeric(static_cast<long>(level_of(blocks, r)))) * g.K[r]);
  return g;
}

// (h, L_f h, ..., L_f^{n-1} h), or the block chains.
std::string chains_text(const std::vector<std::size_t>& blocks) {
  return blocks.size() <= 1 ? "(h, L_f h, ..., L_f^{n-1} h)"
                            : "(h_1, ..., L_f^{k_1-1} h_1, ..., h_p, ..., L_f^{k_p-1} h_p)";
}

// The rule of the gain solve's guard (SolveCorrection with LU; runtime/obsynth/linear_solve.hpp
// lu_conditioning_limit), stated in the report and the generated header.
const char* kSingularGuard =
    "in every RK4 stage the LU factorisation of O(xh) (partial pivoting) must have its smallest "
    "pivot above sqrt(epsilon) times its largest (epsilon of the scalar type: 1.49e-8 in double, "
    "3.45e-4 in float), i.e. an estimated condition number below epsilon^(-1/2); otherwise the "
    "step is rejected (state kept) with Status::singular. O(xh)^-1 maps a correction of z = (h, "
    "L_f h, ...) to x like a Newton step, and epsilon^(-1/2) is Dennis and Schnabel's limit for "
    "such a Jacobian: beyond it at least half of the working digits of the correction are lost, "
    "and near det O = 0 the fixed step no longer resolves xh (the realisation in x crosses a "
    "singularity that z does not have). The limit is not an error bound: near the singular set "
    "xh resolves x only to O(xh)^-1 times the resolution of zh (rounding of a fixed step: about "
    "epsilon |y| / dt in z_2), so an estimate can lag or stall there with Status::ok before the "
    "limit is met (x1' = x2^3, x2' = -x2 in float with dt = 1e-3 stalls at xh2 = 0.02)";

// The generated functions (rhs, O(xh), gain vector), their roles and the LU-solved correction.
void add_hg_functions(ObserverSpec& s, const Model& m, const HighGainStructure& st,
                      const GainChoice& g, const std::string& where_singular) {
  const std::size_t n = m.n();
  const FunctionArg w =
      vector_arg("w", "ObserverState", m.states, FunctionArg::Kind::observer_state);
  const std::vector<GiNaC::symbol> y = measurement_symbols(m);
  const FunctionArg u = input_arg(m), yarg = output_arg(y);
  const ExVec F = m.field();
  s.functions.push_back(
      fn("hg_rhs", "xh' = f(xh) + g(xh, u); the gain term is added by an LU solve with O(xh).",
         {w, u, yarg}, F, 1, "ObserverState"));
  ExVec Ocol;  // column-major
  for (std::size_t c = 0; c < n; ++c)
    for (std::size_t r = 0; r < n; ++r) Ocol.push_back(st.O[r][c]);
  s.functions.push_back(
      fn("observability_matrix",
         "O(xh) = d" + chains_text(st.blocks) + "/dx, the matrix of the gain solve.", {w, u}, Ocol,
         n, "GainMatrix"));
  ExVec v;  // row r of block i: theta^j K_r (y_i - h_i(xh))
  for (std::size_t r = 0; r < n; ++r) {
    const std::size_t i = block_of(st.blocks, r);
    v.push_back(g.gain[r] * (y[i] - m.h[i]));
  }
  s.functions.push_back(fn("gain_vector", "Delta_theta K (y - h(xh)), solved with O(xh).",
                           {w, u, yarg}, v, 1, "GainVector"));
  s.init = InitKind::identity;
  s.update = UpdateKind::ode;
  s.estimate = EstimateKind::identity;
  s.roles.rhs = "hg_rhs";
  SolveCorrection corr;
  corr.factor = SolveCorrection::Factor::lu;
  corr.matrix_function = "observability_matrix";
  corr.vector_function = "gain_vector";
  corr.target_offset = 0;
  corr.dim = n;
  corr.singular_doc = "O(xh) is singular " + where_singular +
                      ", or ill-conditioned: smallest LU pivot <= sqrt(epsilon) x largest";
  s.correction = corr;
}

// What the certificate says of convergence for this theta. Only a rigorous L gives a
// guarantee; a sampled L is an estimate from below of the true one.
// The theorem gives zh -> z in z = (h, L_f h, ...); the realisation in x integrates
// xh' = ... + O(xh)^-1 ..., which needs O(xh) invertible along the estimate. Unless every
// x-dependent factor of det O is proved nonzero on the domain box (zeros_in_box), an estimate
// in the box may meet the singular set, and no guarantee is given in x: the reason, or nothing.
std::optional<std::string> singular_in_box(const Model& m, const HighGainStructure& st) {
  const SampleBoxes boxes = m.sample_boxes();
  std::vector<std::string> meets, unknown;
  for (const auto& f : dependent_factors(st.det, m.states)) {
    const BoxZeros z = zeros_in_box(f, boxes);
    if (z.kind == BoxZeros::somewhere) meets.push_back(z.detail);
    if (z.kind == BoxZeros::unknown) unknown.push_back(z.detail);
  }
  if (!meets.empty())
    return fmt::format("O(x) is singular inside the domain box ({})", fmt::join(meets, "; "));
  if (!unknown.empty())
    return fmt::format("O(x) is not proved nonsingular on the domain box ({})",
                       fmt::join(unknown, "; "));
  return std::nullopt;
}

struct Convergence {
  bool above = false, guaranteed = false;
  std::string kind;             // of L: unbounded, rigorous or sampled
  std::string singular_in_box;  // why the realisation in x is not covered (empty: it is)
};

Convergence convergence(const GainChoice& g, const Certificate& cert,
                        const std::optional<std::string>& singular) {
  Convergence c;
  c.above = g.theta.to_double() > cert.theta_star;
  c.singular_in_box = singular.value_or("");
  c.guaranteed = c.above && cert.rigorous && c.singular_in_box.empty();
  c.kind = cert.unbounded ? "unbounded" : cert.rigorous ? "rigorous" : "sampled";
  return c;
}

// Title, description, class documentation and constants.
void describe_hg(ObserverSpec& s, const GainChoice& g, const Certificate& cert,
                 const Convergence& c, const std::string& where_singular,
                 const std::vector<std::size_t>& blocks) {
  s.title = "High-gain observer (Gauthier-Hammouri-Kupka), realised in the original coordinates";
  s.description = {
      "Observer: high-gain observer (Gauthier-Hammouri-Kupka; seed 002 eq. 3)",
      fmt::format("theta = {}; poles of A - K C: {}; K = [{}]; Delta_theta K = [{}]",
                  to_string(g.theta), numbers_text(g.poles), numbers_text(g.K),
                  numbers_text(g.gain)),
      "Gain applied by an LU solve with O(xh); O singular or ill-conditioned (smallest LU pivot "
      "<= sqrt(epsilon) x largest, in any RK4 stage) -> Status::singular, state kept; O is "
      "singular " +
          where_singular,
      fmt::format("Lipschitz constant of phi in z: L = {} ({}); theta* = {}: convergence {}",
                  up6(cert.L), c.kind, up6(cert.theta_star),
                  c.guaranteed ? "guaranteed"
                  : c.above && !c.singular_in_box.empty() && cert.rigorous
                      ? "not guaranteed in x (O singular in the domain box)"
                  : c.above ? "not proven (sampled L)"
                            : "not guaranteed")};
  s.class_doc = {"  xh' = f(xh) + g(xh, u) + O(xh)^-1 Delta_theta K (y - h(xh))",
                 "with O = d(h, L_f h, ..., L_f^{n-1} h)/dx and Delta_theta = diag(theta, ..., "
                 "theta^n); in z = (h, L_f h, ...) this is the",
                 "observer zh' = A zh + phi(zh, u) + Delta_theta K (y - zh_1). A step where O(xh) "
                 "is singular or ill-conditioned returns Status::singular and keeps the state:",
                 "in any RK4 stage, the smallest LU pivot of O(xh) is at most sqrt(epsilon) times "
                 "the largest (epsilon of Scalar; obsynth::lu_conditioning_limit)."};
  if (blocks.size() > 1) {
    s.class_doc[1] =
        "with O = d" + chains_text(blocks) + "/dx (indices " + indices_text(blocks) +
        ") and Delta_theta = blockdiag(diag(theta, ..., theta^{k_i})); in z this is the";
    s.class_doc[2] =
        "observer zh' = A zh + phi(zh, u) + Delta_theta K (y - C zh), C zh = (zh_{1,1}, ..., "
        "zh_{p,1}). A step where O(xh) is singular or ill-conditioned returns Status::singular "
        "and keeps the state:";
  }
  s.constants.push_back({"theta", {g.theta}, "high-gain parameter"});
  s.constants.push_back(
      {"poles", g.poles, "poles of A - K C (the error poles are theta times these)"});
  s.constants.push_back(
      {"K", g.K, "gain of the unscaled error system, char(A - K C) = prod (s - pole)"});
  s.constants.push_back({"gain", g.gain, "Delta_theta K"});
}

// The "theta" report row: given, or chosen from theta* (and why).
std::string theta_text(const GainChoice& g, const Certificate& cert) {
  if (g.theta_given) return to_string(g.theta) + " (--theta)";
  if (!std::isfinite(cert.theta_star) || cert.theta_star * kThetaMargin > kThetaCap)
    return fmt::format(
        "{} (default: the cap; theta* = {} is unusable: no theta up to the cap {:g} is covered "
        "by the theorem)",
        to_string(g.theta), up6(cert.theta_star), kThetaCap);
  return fmt::format("{} (default: {:g} theta* = {} rounded up, at least {:g}, at most {:g})",
                     to_string(g.theta), kThetaMargin, up6(cert.theta_star), kThetaFloor,
                     kThetaCap);
}

// The "convergence" report row.
std::string convergence_text(const GainChoice& g, const Certificate& cert, const Convergence& c) {
  if (c.above && cert.rigorous && !c.singular_in_box.empty())
    return fmt::format(
        "not guaranteed in x: theta = {} > theta* = {} gives zh -> z in z = (h, L_f h, ...), "
        "but {}: the realisation in x (a solve with O(xh)) is not covered where the estimate "
        "meets that set (Status::singular when it reaches it numerically)",
        to_string(g.theta), up6(cert.theta_star), c.singular_in_box);
  // Whatever theta: with O singular in the box the realisation in x is not covered there.
  const std::string singular =
      c.singular_in_box.empty()
          ? std::string()
          : "; and " + c.singular_in_box +
                ": the realisation in x (a solve with O(xh)) is not covered where the estimate "
                "meets that set, for any theta";
  if (cert.unbounded)
    return "not guaranteed: the triangular nonlinearity has no finite Lipschitz bound on the "
           "domain box (see the bounds above)" +
           singular;
  if (c.above && !cert.rigorous)
    return fmt::format(
               "not proven: theta = {} > theta* = {}, but L is sampled (an estimate, not an upper "
               "bound)",
               to_string(g.theta), up6(cert.theta_star)) +
           singular;
  if (c.guaranteed)
    return fmt::format(
        "guaranteed: theta = {} > theta* = {} (while xh and x stay in the domain box, where L "
        "holds)",
        to_string(g.theta), up6(cert.theta_star));
  return fmt::format("not guaranteed by the theorem: theta = {} <= theta* = {} (short by {}){}",
                     to_string(g.theta), up6(cert.theta_star),
                     up6(cert.theta_star - g.theta.to_double()),
                     singular.empty() ? "; raise --theta" : "") +
         singular;
}

// The report rows and the summary.
void report_hg(ObserverSpec& s, const HighGainStructure& st, const GainChoice& g,
               const Certificate& cert, const Convergence& c, const std::string& where_singular,
               const DesignOptions& o) {
  s.largest_safe_step = rk4_safe_period(g.theta, g.poles);
  s.report = {
      {"coordinates", high_gain_coordinates(st.blocks) +
                          (st.blocks.size() > 1 ? ", output first in each block (seed 002 "
                                                  "convention per block)"
                                                : ", output first (seed 002 convention)")},
      {"theta", theta_text(g, cert)},
      {"largest safe sample period",
       fmt::format("{:.3g} s (RK4 stability on the fastest error pole theta max|pole|; the "
                   "firmware's step() must run at least this often)",
                   rk4_safe_period(g.theta, g.poles))},
      {"poles", numbers_text(g.poles) + (o.find("poles") ? "" : " (default)")},
      {"K", numbers_text(g.K)},
      {"Delta_theta K", numbers_text(g.gain)},
      {"det O", to_string(st.det)},
      {"O singular", where_singular},
      {"singular guard", kSingularGuard},
      {"phi (in x)", fmt::format("[{}]", fmt::join(to_strings(st.phi), ", "))},
      {"Lipschitz bounds", fmt::format("{}", fmt::join(cert.entries, "; "))},
      {"Lipschitz constant L",
       fmt::format("{} ({}; spectral norm of the entry bounds, rounded up)", up6(cert.L), c.kind)},
      {"lambda_max(P)",
       fmt::format("{} (P: (A - K C)^T P + P (A - K C) = -I; rounded up)", up6(cert.lambda_P))},
      {"theta*", fmt::format("{} = max(1, 2 lambda_max(P) L) ({}, rounded up)",
                             up6(cert.theta_star), c.kind)},
      {"convergence", convergence_text(g, cert, c)}};
  s.summary = fmt::format(
      "high-gain observer, theta = {}, poles {} (scaled by theta), gain Delta_theta K = [{}]; L = "
      "{} ({}), theta* = {}: convergence {}",
      to_string(g.theta), numbers_text(g.poles), numbers_text(g.gain), up6(cert.L), c.kind,
      up6(cert.theta_star),
      c.guaranteed                                             ? "guaranteed"
      : c.above && !c.singular_in_box.empty() && cert.rigorous ? "not guaranteed in x"
      : c.above                                                ? "not proven"
                                                               : "not guaranteed");
}

// The blocks' sizes: the analysis' observability indices (p = 1: {n} whatever the analysis).
std::vector<std::size_t> indices(const Analysis& a) {
  if (a.model.p() == 1) return {a.model.n()};
  return a.observability.indices;
}

// The certificate behind the verdict, with the default poles and theta (the main job's
// choice): withdrawn where it shows the design useless (no finite L, theta* above the cap, O
// singular inside the box), otherwise rigorous (Arb L) or partial (sampled L).
void assess(const Analysis& a, Verdict& v) {
  const Model& m = a.model;
  const HighGainStructure st = high_gain_structure(m, indices(a));
  if (!st.failures.empty()) {
    v = Verdict{false, st.failures, Guarantee::none, ""};
    return;
  }
  const std::vector<numeric> poles = chosen_poles({}, st.blocks);
  const Certificate cert = certify(m, st, high_gain_K(poles, st.blocks));
  const auto singular = singular_in_box(m, st);
  if (cert.unbounded || cert.theta_star * kThetaMargin > kThetaCap) {
    v.applies = false;
    v.reasons = {fmt::format(
        "uniformly observable, but its certificate makes it useless here: theta* = {} ({} L = "
        "{}){}; no theta up to the cap {:g} is covered by the theorem",
        up6(cert.theta_star), cert.rigorous ? "rigorous" : "sampled", up6(cert.L),
        cert.unbounded ? " (phi has no finite Lipschitz bound on the domain box)" : "", kThetaCap)};
    return;
  }
  if (singular && singular->find("inside the domain box") != std::string::npos) {
    v.applies = false;
    v.reasons = {"uniformly observable only off det O = 0, and " + *singular +
                 ": the realisation in x solves with O(xh) and stalls there"};
    return;
  }
  const numeric theta = automatic_theta(cert.theta_star);
  const std::string claim =
      fmt::format("theta = {} > theta* = {} (L = {}, {})", to_string(theta), up6(cert.theta_star),
                  up6(cert.L), cert.rigorous ? "Arb bound over the box" : "sampled");
  if (singular) {
    v.guarantee = Guarantee::none;
    v.guarantee_text = claim + " gives zh -> z, but " + *singular;
  } else {
    // Even with a rigorous L the theorem holds only while xh stays in the box, and the
    // high-gain transient peaks like theta^(n-1), which nothing here bounds: on a sub-region of
    // the state-estimate space, not the domain (a ship model left the box in its first step).
    v.guarantee = Guarantee::partial;
    v.guarantee_text =
        claim + (cert.rigorous ? ", proved while xh stays in the domain box; the transient's "
                                 "peaking (like theta^(n-1)) is not bounded"
                               : ": L is an estimate from samples, not a bound");
  }
}

ObserverSpec build(const Analysis& a, const DesignOptions& o) {
  const Model& m = a.model;
  const HighGainStructure st = high_gain_structure(m, indices(a));
  if (!st.failures.empty())
    throw UserError(SourceLoc{m.file, 0, 0}, fmt::format("method 'high-gain' does not apply: {}",
                                                         fmt::join(st.failures, "; ")));
  const std::size_t n = m.n();
  std::vector<numeric> poles = chosen_poles(o, st.blocks);
  const Certificate cert = certify(m, st, high_gain_K(poles, st.blocks));
  const GainChoice g = choose_gain(o, std::move(poles), cert.theta_star, st.blocks);
  const std::string where_singular = singular_set(m, st);

  ObserverSpec s;
  s.method = "high-gain";
  s.class_suffix = "HighGain";
  s.state_size = n;
  s.state_name = "xh";
  s.state_doc = "the estimate itself";
  s.params = runtime_params(m);
  s.functions = model_functions(m);
  add_hg_functions(s, m, st, g, where_singular);
  const Convergence c = convergence(g, cert, singular_in_box(m, st));
  describe_hg(s, g, cert, c, where_singular, st.blocks);
  report_hg(s, st, g, cert, c, where_singular, o);
  if (!c.guaranteed)
    s.warnings.push_back("the high-gain observer as built is " + convergence_text(g, cert, c));
  return s;
}

}  // namespace

Design high_gain_design() {
  Design d;
  d.name = "high-gain";
  d.summary =
      "high-gain observer for uniformly observable systems, p >= 1 outputs in block-triangular "
      "form (seed 002 eq. 3; gain through an LU solve with O(xh))";
  d.options = {
      {"poles",
       "error poles, comma-separated negative reals (canonical: of A - K e_n^T; high-gain: "
       "of A - K C, scaled by theta, split over the blocks in output order)",
       "-2, -2.5, -3, ..."},
      {"theta",
       "high-gain: gain scale theta (Delta_theta = diag(theta, ..., theta^k) per block); "
       "kalman-theta: forgetting rate theta of S",
       "1.25 theta* within [5, 200] (high-gain), 5 (kalman-theta)"}};
  d.plan = stateless_plan<applies, build, assess>;
  d.has_assessment = true;
  d.observes_along_inputs = true;
  d.along_inputs_note = "if uniformly observable";
  d.needs_uniform_observability = true;
  d.max_outputs = 0;  // any p: one block per output (observability indices)
  return d;
}

}  // namespace obsynth
