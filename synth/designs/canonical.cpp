#include "designs/canonical.hpp"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <map>
#include <optional>

#include "analysis/conditions.hpp"
#include "designs/design_helpers.hpp"
#include "designs/options.hpp"
#include "front/fresh_names.hpp"
#include "symbolic/expr_print.hpp"
#include "symbolic/symbolic.hpp"
#include "symbolic/zero_test.hpp"

namespace obsynth {

using GiNaC::ex;
using GiNaC::numeric;

std::vector<numeric> default_poles(std::size_t n) {
  std::vector<numeric> p;
  for (std::size_t k = 0; k < n; ++k) p.push_back(-2 - numeric(static_cast<long>(k), 2));
  return p;
}

std::vector<numeric> gains_from_poles(const std::vector<numeric>& poles) {
  GiNaC::symbol s("s");
  ex poly = 1;
  for (const auto& q : poles) poly *= (s - q);
  poly = GiNaC::expand(poly);
  std::vector<numeric> K;
  for (std::size_t i = 0; i < poles.size(); ++i)
    K.push_back(GiNaC::ex_to<numeric>(poly.coeff(s, static_cast<int>(i))));  // K_{i+1} = c_i
  return K;
}

ExVec outputs_at_base_point(const Analysis& a) {
  const Model& m = a.canonical_model();
  GiNaC::exmap at_x0;
  for (std::size_t i = 0; i < m.n() && i < a.canonical.base_point.size(); ++i)
    at_x0[m.states[i]] = a.canonical.base_point[i];
  ExVec y0;
  for (const auto& h : m.h) y0.push_back(simplify(h.subs(at_x0)));
  return y0;
}

std::vector<std::vector<numeric>> closed_loop_matrix(const CanonicalForm& cf,
                                                     const std::vector<numeric>& K) {
  const std::size_t n = K.size();
  std::vector<std::vector<numeric>> A(n, std::vector<numeric>(n, 0));
  for (std::size_t i = 0; i < n; ++i) {
    if (i != cf.block_start(cf.block_of(i))) A[i][i - 1] = 1;
    A[i][cf.block_end(cf.block_of(i))] -= K[i];
  }
  return A;
}

std::string closed_loop_text(const CanonicalForm& cf) {
  return cf.outputs() <= 1 ? "A - K e_n^T" : "A - K C";
}

std::vector<std::string> canonical_form_failures(const Analysis& a) {
  const CanonicalForm& cf = a.canonical;
  if (!cf.applicable) return {cf.not_applicable};
  std::vector<std::string> failing;
  auto fails = [&](const std::vector<BracketCheck>& list, auto name) {
    for (const auto& b : list)
      if (!b.holds()) {
        std::string text = name(cf, b);
        failing.push_back(text.replace(text.rfind(" = "), 3, " != "));
      }
  };
  fails(cf.drift, drift_condition_name);
  fails(cf.input, input_condition_name);
  fails(cf.output, output_condition_name);
  if (!failing.empty())
    return {fmt::format("not linearizable by output injection ({}){}", fmt::join(failing, ", "),
                        cf.frame_note.empty() ? "" : "; " + cf.frame_note)};
  if (cf.l_kind != Availability::symbolic) return {"l(u, y) has no closed form: " + cf.l_note};
  return {};
}

GeneratedFunction inverse_function(const Analysis& a) {
  const Model& m = a.canonical_model();
  const CanonicalForm& cf = a.canonical;
  GeneratedFunction f;
  f.name = "T_inverse";
  f.doc = "Closed-form inverse x = T^-1(z), as its elimination sequence.";
  f.args = {vector_arg("z", "State", cf.z)};
  f.out_rows = m.n();
  f.out_type = "State";
  if (cf.T_inverse_steps.empty()) {
    f.outputs = cf.T_inverse;
    return f;
  }
  for (const auto& step : cf.T_inverse_steps) f.lets.push_back({m.states[step.state], step.value});
  f.outputs.assign(m.states.begin(), m.states.end());
  return f;
}

namespace {

enum class Realisation { z, x };

struct Choices {
  std::vector<numeric> poles, K;
  std::string poles_reason;  // how the poles were chosen
  double peaking = 1;        // predicted peaking of the scaled z error (predicted_peaking)
  Realisation realisation = Realisation::z;
  std::string realisation_reason;
  bool exact = true;  // z realisation: exact discretisation, else RK4
};

// The range of each z_i = T_i(x) over samples of the domain box (0 where T is not available).
std::vector<double> z_ranges(const Analysis& a) {
  const Model& m = a.canonical_model();
  const ExVec& T = a.canonical.T;
  std::vector<double> lo(T.size(), HUGE_VAL), hi(T.size(), -HUGE_VAL), range(m.n(), 0.0);
  if (a.canonical.T_kind != Availability::symbolic || T.size() != m.n()) return range;
  for (const auto& pt : sample_points(m.all_symbols(), m.sample_boxes(), 64, 0x7a3e)) {
    for (std::size_t i = 0; i < T.size(); ++i) {
      numeric v;
      if (!evaluate_real(T[i], pt, 17, v)) continue;
      lo[i] = std::min(lo[i], v.to_double());
      hi[i] = std::max(hi[i], v.to_double());
    }
  }
  for (std::size_t i = 0; i < T.size(); ++i)
    if (hi[i] > lo[i] && std::isfinite(hi[i] - lo[i])) range[i] = hi[i] - lo[i];
  return range;
}

// The model's time scale in the canonical form: z_{i-1} ~ d z_i / dt, so the ranges of z_1 ..
// z_n over the box fall geometrically by omega: omega = (range z_1 / range z_n)^(1/(n-1)),
// clamped to [1e-3, 1e4] rad/s; 1 when the ranges are not available.
double time_scale(const std::vector<double>& range) {
  const std::size_t n = range.size();
  if (n < 2 || !(range.front() > 0) || !(range.back() > 0)) return 1;
  const double w = std::pow(range.front() / range.back(), 1.0 / static_cast<double>(n - 1));
  return std::isfinite(w) ? std::clamp(w, 1e-3, 1e4) : 1;
}

// Error poles -omega (2, 2.5, 3, ...), rounded to 3 significant digits (exact rationals).
std::vector<numeric> scaled_poles(double omega, std::size_t n) {
  std::vector<numeric> p;
  for (std::size_t k = 0; k < n; ++k) {
    const double v = omega * (2 + 0.5 * static_cast<double>(k));
    const double unit = std::pow(10.0, std::floor(std::log10(v)) - 2);
    const long digits = std::lround(v / unit);
    p.push_back(unit >= 1 ? -numeric(digits * std::lround(unit))
                          : -numeric(digits, std::lround(1 / unit)));
  }
  return p;
}

// Largest amplification of an initial error measured in box units: max over t of the row-sum
// norm of S^-1 exp(A_cl t) S, S = diag(range z_i), A_cl = A - K C (one output: z_1' = -K_1 z_n,
// z_i' = z_{i-1} - K_i z_n), by RK4 over ten slowest time constants.
double predicted_peaking(const std::vector<numeric>& poles,
                         const std::vector<std::vector<numeric>>& closed_loop,
                         const std::vector<double>& range) {
  const auto n = static_cast<Eigen::Index>(poles.size());
  Eigen::MatrixXd A(n, n);
  for (Eigen::Index i = 0; i < n; ++i)
    for (Eigen::Index j = 0; j < n; ++j)
      A(i, j) = closed_loop[static_cast<std::size_t>(i)][static_cast<std::size_t>(j)].to_double();
  Eigen::VectorXd s(n);
  for (Eigen::Index i = 0; i < n; ++i)
    s(i) = range[static_cast<std::size_t>(i)] > 0 ? range[static_cast<std::size_t>(i)] : 1;
  A = s.cwiseInverse().asDiagonal() * A * s.asDiagonal();
  double fast = 0, slow = HUGE_VAL;
  for (const auto& q : poles) {
    fast = std::max(fast, std::abs(q.to_double()));
    slow = std::min(slow, std::abs(q.to_double()));
  }
  const double dt = 0.05 / fast;
  Eigen::MatrixXd E = Eigen::MatrixXd::Identity(n, n);
  double peak = 1;
  for (double t = 0; t < 10 / slow; t += dt) {
    const Eigen::MatrixXd k1 = A * E, k2 = A * (E + dt / 2 * k1), k3 = A * (E + dt / 2 * k2),
                          k4 = A * (E + dt * k3);
    E += dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
    peak = std::max(peak, E.cwiseAbs().rowwise().sum().maxCoeff());
  }
  return peak;
}

// The "largest safe sample period" row: the exact step is stable at any period (Phi = e^{A_cl
// dt}); RK4 needs dt max|pole| within its stability interval [-2.785, 0].
double rk4_safe_step(const Choices& c) {
  if (c.realisation == Realisation::z && c.exact) return 0;  // any
  double fastest = 0;
  for (const auto& q : c.poles) fastest = std::max(fastest, std::abs(q.to_double()));
  return 2.785 / fastest;
}

std::string safe_period_text(const Choices& c) {
  if (rk4_safe_step(c) == 0)
    return "any: the linear error dynamics are discretised exactly (Phi = exp(A_cl dt)); l(u, y) "
           "is held over the step, so the period sets only how well u and y are sampled";
  return fmt::format("{:.3g} s (RK4 stability on the fastest error pole)", rk4_safe_step(c));
}

// The "predicted peaking" report row.
std::string peaking_text(double peaking) {
  const std::string base = fmt::format(
      "{:.3g}: an initial error of 20 % of the box (in each z_i, scaled by its range over the "
      "box) grows to at most {:.3g} box widths before it decays (sampled ranges)",
      peaking, 0.2 * peaking);
  return 0.2 * peaking > 1 ? base +
                                 "; the estimate leaves the domain box on the way: choose "
                                 "slower or better-spread poles (--poles)"
                           : base;
}

std::vector<numeric> chosen_poles(const DesignOptions& o, std::size_t n) {
  std::vector<numeric> poles = real_list_option(o, "poles");
  if (poles.empty()) return default_poles(n);
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

// The poles of each block (consecutive slices of `poles`, block by block) -> K, block by block.
std::vector<numeric> block_gains(const CanonicalForm& cf, const std::vector<numeric>& poles) {
  std::vector<numeric> K;
  for (std::size_t b = 0; b < cf.outputs(); ++b) {
    const auto first = poles.begin() + static_cast<long>(cf.block_start(b));
    const auto Kb = gains_from_poles({first, first + static_cast<long>(cf.blocks[b])});
    K.insert(K.end(), Kb.begin(), Kb.end());
  }
  return K;
}

// Default poles: per block, -omega_i (2, 2.5, 3, ...) with the block's time scale (a block of
// one coordinate has none of its own: it takes the fastest of the others, else 1).
void default_block_poles(const CanonicalForm& cf, const std::vector<double>& range, Choices& c) {
  std::vector<double> omega;
  double fastest = 0;
  for (std::size_t b = 0; b < cf.outputs(); ++b) {
    const auto first = range.begin() + static_cast<long>(cf.block_start(b));
    omega.push_back(cf.blocks[b] > 1 ? time_scale({first, first + static_cast<long>(cf.blocks[b])})
                                     : 0);
    fastest = std::max(fastest, omega.back());
  }
  std::vector<std::string> scales;
  for (std::size_t b = 0; b < cf.outputs(); ++b) {
    if (omega[b] == 0) omega[b] = fastest > 0 ? fastest : 1;
    const auto p = scaled_poles(omega[b], cf.blocks[b]);
    c.poles.insert(c.poles.end(), p.begin(), p.end());
    scales.push_back(fmt::format("{:.3g}", omega[b]));
  }
  if (cf.outputs() == 1)
    c.poles_reason = fmt::format(
        "default: -omega (2, 2.5, 3, ...) with the model's time scale omega = {:.3g} rad/s = "
        "(range z_1 / range z_n)^(1/(n-1)) over the domain box (sampled)",
        omega[0]);
  else
    c.poles_reason = fmt::format(
        "default: per output block i, -omega_i (2, 2.5, 3, ...) with the block's time scale "
        "omega_i = (range z_(i,1) / range z_(i,k_i))^(1/(k_i-1)) over the domain box (sampled; a "
        "block of one coordinate takes the fastest other): omega = {} rad/s",
        fmt::join(scales, ", "));
}

Choices choose(const Analysis& a, const DesignOptions& o) {
  const CanonicalForm& cf = a.canonical;
  Choices c;
  const std::vector<double> range = z_ranges(a);
  if (o.find("poles")) {
    c.poles = chosen_poles(o, a.model.n());
    c.poles_reason =
        cf.outputs() == 1 ? "--poles" : "--poles, block by block in the order of the outputs";
  } else {
    default_block_poles(cf, range, c);
  }
  c.K = block_gains(cf, c.poles);
  c.peaking = predicted_peaking(c.poles, closed_loop_matrix(cf, c.K), range);
  const bool T_closed = cf.T_kind == Availability::symbolic;
  const bool Tinv_closed = cf.T_inverse_kind == Availability::symbolic;
  if (const auto r = choice_option(o, "realisation", {"z", "x"})) {
    c.realisation = *r == "z" ? Realisation::z : Realisation::x;
    c.realisation_reason = "chosen with --realisation";
    if (c.realisation == Realisation::z && !T_closed)
      throw UserError(SourceLoc{}, "--realisation z needs T in closed form: " + cf.T_note);
  } else if (T_closed && Tinv_closed) {
    c.realisation_reason =
        "T and T^-1 are closed-form: the z realisation integrates a linear system";
  } else {
    c.realisation = Realisation::x;
    c.realisation_reason = T_closed
                               ? "T^-1 has no closed form: the x realisation needs no inverse"
                               : "T has no closed form: the x realisation needs neither T nor T^-1";
  }
  c.exact = choice_option(o, "integrator", {"exact", "rk4"}).value_or("exact") == "exact";
  return c;
}

GeneratedFunction fn(const std::string& name, const std::string& doc, std::vector<FunctionArg> args,
                     ExVec out, std::size_t cols = 1, const std::string& out_type = "State") {
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

// T, T^-1, l and the frame, as the realisation needs them.
void add_canonical_maps(const Analysis& a, const Choices& c, ObserverSpec& s) {
  const Model& m = a.canonical_model();
  const CanonicalForm& cf = a.canonical;
  const bool zreal = c.realisation == Realisation::z;
  const bool Tinv_closed = cf.T_inverse_kind == Availability::symbolic;
  const FunctionArg x = state_arg(m), u = input_arg(m), y = output_arg(cf.y);
  if (cf.T_kind == Availability::symbolic)
    s.functions.push_back(
        fn("T", "Diffeomorphism z = T(x) to observer canonical form, T(x0) = 0.", {x}, cf.T));
  if (Tinv_closed) s.functions.push_back(inverse_function(a));
  s.functions.push_back(
      fn("l", "Output injection l(u, y) of the canonical form z' = A z + l(u, y).", {u, y}, cf.l));
  if (!zreal || !Tinv_closed)
    s.functions.push_back(fn("frame", "Frame [tau_1 ... tau_n](x) = (dT/dx)^-1, columns tau_k.",
                             {x}, frame_column_major(cf), cf.frame.size(), "Frame"));
}

// c = B b: b the distinct non-constant factors of the terms of the expanded c (ordered by their
// printed text; a constant term gets the entry 1), B their rational coefficients. Used when
// it costs fewer multiply-adds per step than c itself, n k < n^2 + nnz(B): the exact step then
// applies Gamma B (folded once per dt) to b, instead of computing the n entries of c and Gamma c.
struct InputSplit {
  ExVec basis;
  std::vector<std::vector<numeric>> B;  // rows
};

ExVec terms_of(const ex& e) {
  const ex x = GiNaC::expand(e);
  return GiNaC::is_a<GiNaC::add>(x) ? ExVec(x.begin(), x.end()) : ExVec{x};
}

// A rational term P/Q in one of `vars` with deg P >= deg Q > 0 is split by polynomial division,
// P/Q = quo + rem/Q (e.g. y^3/(1+y^2) = y - y/(1+y^2)), so that its pieces are shared with the
// other terms; nullopt when there is nothing to divide.
std::optional<ExVec> divided(const ex& t, const std::vector<GiNaC::symbol>& vars) {
  const ex nd = t.numer_denom();
  const ex num = nd.op(0), den = nd.op(1);
  if (GiNaC::is_a<numeric>(den)) return std::nullopt;
  for (const auto& v : vars) {
    if (!den.has(v) || !num.is_polynomial(v) || !den.is_polynomial(v)) continue;
    if (num.degree(v) < den.degree(v) || den.degree(v) <= 0) continue;
    const ex q = GiNaC::quo(num, den, v), r = GiNaC::rem(num, den, v);
    ExVec out = terms_of(q);
    if (!r.is_zero())
      for (const ex& piece : terms_of(r)) out.push_back(piece / den);
    return out;
  }
  return std::nullopt;
}

std::optional<InputSplit> split_step_constant(const ExVec& c,
                                              const std::vector<GiNaC::symbol>& vars) {
  const std::size_t n = c.size();
  std::map<std::string, ex> basis;                       // printed text -> term
  std::vector<std::map<std::string, numeric>> coeff(n);  // row -> basis text -> coefficient
  for (std::size_t i = 0; i < n; ++i) {
    ExVec work = terms_of(c[i]);
    for (std::size_t w = 0; w < work.size(); ++w) {
      const ex t = work[w];
      if (t.is_zero()) continue;
      numeric k = 1;
      ex rest = 1;
      if (GiNaC::is_a<numeric>(t)) {
        k = GiNaC::ex_to<numeric>(t);
      } else if (GiNaC::is_a<GiNaC::mul>(t)) {
        for (const ex& f : t)
          if (GiNaC::is_a<numeric>(f))
            k *= GiNaC::ex_to<numeric>(f);
          else
            rest *= f;
      } else {
        rest = t;
      }
      if (!k.is_rational()) return std::nullopt;
      if (work.size() < 64 * n)  // a bound on the work, never reached by a sensible model
        if (const auto pieces = divided(rest, vars)) {
          for (const ex& piece : *pieces) work.push_back(k * piece);
          continue;
        }
      const std::string key = to_string(rest);
      basis.emplace(key, rest);
      auto [it, fresh] = coeff[i].emplace(key, k);
      if (!fresh) it->second += k;
    }
  }
  InputSplit out;
  std::size_t nnz = 0;
  std::vector<std::string> keys;
  for (const auto& [key, term] : basis) {
    bool used = false;
    for (std::size_t i = 0; i < n; ++i) {
      const auto it = coeff[i].find(key);
      used = used || (it != coeff[i].end() && !it->second.is_zero());
    }
    if (!used) continue;
    keys.push_back(key);
    out.basis.push_back(term);
  }
  out.B.assign(n, std::vector<numeric>(keys.size(), 0));
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = 0; j < keys.size(); ++j) {
      const auto it = coeff[i].find(keys[j]);
      if (it == coeff[i].end() || it->second.is_zero()) continue;
      out.B[i][j] = it->second;
      ++nnz;
    }
  // Worth it when b has no more varying entries than c (a constant entry 1 costs no multiply)
  // and fewer multiply-adds: measured on the constructed chains, b with more entries than c
  // (n = 3: 4 varying + 1 against 3) makes the vectorised step slower despite fewer scalar
  // operations in c.
  const std::size_t k = keys.size();
  std::size_t varying = 0;
  for (const ex& b : out.basis) varying += GiNaC::is_a<numeric>(b) ? 0 : 1;
  if (k == 0 || varying > n || n * k >= n * n + nnz) return std::nullopt;
  return out;
}

void build_z_realisation(const Analysis& a, const Choices& c, ObserverSpec& s) {
  const Model& m = a.canonical_model();
  const CanonicalForm& cf = a.canonical;
  const std::size_t n = m.n();
  const ExVec y0 = outputs_at_base_point(a);
  const auto zh = fresh_symbols(m, "zh", n), cs = fresh_symbols(m, "c", n);
  const auto A_cl = closed_loop_matrix(cf, c.K);
  ExVec step_constant, z_rhs;
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t b = cf.block_of(i);
    step_constant.push_back(cf.l[i] + c.K[i] * (cf.y[b] - y0[b]));
    ex rhs = cs[i];
    for (std::size_t j = 0; j < n; ++j) rhs += A_cl[i][j] * zh[j];
    z_rhs.push_back(rhs);
  }
  const bool one = cf.outputs() == 1;
  s.functions.push_back(fn("step_constant", "c = l(u, y) + K (y - y0), constant over a step.",
                           {input_arg(m), output_arg(cf.y)}, step_constant));
  s.functions.push_back(fn("z_rhs",
                           one ? "zh' = A zh - K zh_n + c (the z-realisation right-hand side)."
                               : "zh' = A zh - K C zh + c (the z-realisation right-hand side).",
                           {vector_arg("z", "State", zh, FunctionArg::Kind::observer_state),
                            vector_arg("c", "State", cs)},
                           z_rhs));
  s.state_name = "zh";
  s.state_doc = "zh = T(xh), in canonical coordinates";
  s.init = InitKind::function;
  s.roles.init = "T";
  s.update = UpdateKind::linear_exact;
  s.rk4_for_linear = !c.exact;
  s.roles.step_constant = "step_constant";
  s.roles.rhs = "z_rhs";
  if (c.exact) {
    std::vector<GiNaC::symbol> vars(m.inputs.begin(), m.inputs.end());
    vars.insert(vars.end(), cf.y.begin(), cf.y.end());
    if (auto split = split_step_constant(step_constant, vars)) {
      s.functions.push_back(fn("step_basis",
                               "b with c = l(u, y) + K (y - y0) = B b (B: the class's input map).",
                               {input_arg(m), output_arg(cf.y)}, split->basis, 1, "Basis"));
      s.roles.step_basis = "step_basis";
      s.input_map = std::move(split->B);
    }
  }
  s.closed_loop = A_cl;
  if (cf.T_inverse_kind == Availability::symbolic) {
    s.estimate = EstimateKind::function;
    s.roles.estimate = "T_inverse";
  } else {
    s.estimate = EstimateKind::newton;
    s.roles.newton_map = "T";
    s.roles.newton_inverse_jacobian = "frame";
  }
}

void build_x_realisation(const Analysis& a, const Choices& c, ObserverSpec& s) {
  const Model& m = a.canonical_model();
  const CanonicalForm& cf = a.canonical;
  const std::size_t n = m.n();
  const ExVec F = m.field();
  GiNaC::exmap y_to_yhat;
  for (std::size_t q = 0; q < cf.y.size(); ++q) y_to_yhat[cf.y[q]] = m.h[q];
  std::vector<ex> v(n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t b = cf.block_of(i);
    v[i] = cf.l[i] - cf.l[i].subs(y_to_yhat) + c.K[i] * (cf.y[b] - m.h[b]);
  }
  ExVec rhs;
  for (std::size_t r = 0; r < n; ++r) {
    ex acc = F[r];
    for (std::size_t k = 0; k < n; ++k) acc += cf.frame[k][r] * v[k];
    rhs.push_back(acc);
  }
  s.functions.push_back(fn("x_rhs",
                           "xh' = f + g + [tau](xh) (l(u,y) - l(u,h(xh)) + K (y - h(xh))).",
                           {state_arg(m), input_arg(m), output_arg(cf.y)}, rhs));
  s.state_name = "xh";
  s.state_doc = "the estimate itself";
  s.init = InitKind::identity;
  s.update = UpdateKind::ode;
  s.roles.rhs = "x_rhs";
  s.estimate = EstimateKind::identity;
}

// "z2, z4": the coordinates the outputs read.
std::string block_ends_text(const CanonicalForm& cf) {
  std::vector<std::string> ends;
  for (std::size_t b = 0; b < cf.outputs(); ++b) ends.push_back(cf.z_name(cf.block_end(b)));
  return fmt::format("{}", fmt::join(ends, ", "));
}

std::string numbers_text(const std::vector<numeric>& v) {
  std::vector<std::string> s;
  for (const auto& q : v) s.push_back(to_string(q));
  return fmt::format("{}", fmt::join(s, ", "));
}

void describe(const Analysis& a, const Choices& c, ObserverSpec& s) {
  const bool zreal = c.realisation == Realisation::z;
  const bool newton = s.estimate == EstimateKind::newton;
  s.title = zreal ? "Canonical-form Luenberger observer, realised in z coordinates"
                  : "Canonical-form Luenberger observer, realised in the original coordinates";
  s.description.push_back(
      "Observer: canonical-form Luenberger observer (Krener-Isidori; seeds 001 §7, 003)");
  s.description.push_back(fmt::format("Realisation: {} ({})",
                                      zreal ? "z coordinates" : "original coordinates",
                                      c.realisation_reason));
  if (zreal)
    s.description.push_back(fmt::format(
        "T^-1: {}", newton ? "runtime Newton with [tau] as inverse Jacobian" : "closed form"));
  const std::string integrator =
      !zreal    ? "RK4 with u, y held over a step"
      : c.exact ? "exact zero-order-hold discretisation (Phi = e^{A_cl dt}, Gamma)"
                : "RK4 with u, y held over a step";
  s.description.push_back(fmt::format("Error poles: {}; K = [{}]; integrator {}",
                                      numbers_text(c.poles), numbers_text(c.K), integrator));
  const CanonicalForm& cf = a.canonical;
  const std::string A_cl = closed_loop_text(cf);
  if (zreal)
    s.class_doc = {cf.outputs() == 1 ? "  zh' = A zh + l(u, y) + K (y - y0 - zh_n),  xh = T^-1(zh)"
                                     : "  zh' = A zh + l(u, y) + K (y - y0 - C zh),  xh = T^-1(zh)",
                   fmt::format("The error z - zh obeys e' = ({}) e exactly: poles {}.", A_cl,
                               numbers_text(c.poles))};
  else
    s.class_doc = {
        "  xh' = f(xh) + g(xh, u) + [tau](xh) (l(u, y) - l(u, h(xh)) + K (y - h(xh)))",
        "needing neither T nor T^-1 at run time; in z = T(x) the error is exactly linear "
        "with",
        fmt::format("poles {}.", numbers_text(c.poles))};
  s.constants.push_back({"poles", c.poles, fmt::format("error poles of ({})", A_cl)});
  s.constants.push_back({"K", c.K, "output-injection gain, K_i = c_{i-1} of prod (s - pole)"});
  s.largest_safe_step = rk4_safe_step(c);
  s.report = {{"realisation", fmt::format("{} ({})", zreal ? "z" : "x", c.realisation_reason)},
              {"poles", numbers_text(c.poles) + " (" + c.poles_reason + ")"},
              {"predicted peaking", peaking_text(c.peaking)},
              {"K", numbers_text(c.K)},
              {"integrator", integrator},
              {"largest safe sample period", safe_period_text(c)}};
  if (0.2 * c.peaking > 1)
    s.warnings.push_back(fmt::format(
        "the canonical observer's predicted peaking is {:.3g}: from a 20 % initial error the "
        "estimate may leave the domain box by {:.3g} box widths before it converges; choose "
        "slower or better-spread poles (--poles)",
        c.peaking, 0.2 * c.peaking));
  if (zreal)
    s.report.push_back(
        {"T^-1", newton ? "runtime Newton with [tau] as inverse Jacobian" : "closed form"});
  if (cf.outputs() > 1)
    s.report.push_back(
        {"blocks", fmt::format("{} (observability indices; C z = the block ends: {})",
                               fmt::join(cf.blocks, ", "), block_ends_text(cf))});
  s.summary = fmt::format("canonical-form observer, {} realisation ({}), poles {}, K = [{}]",
                          zreal ? "z" : "x", c.realisation_reason, numbers_text(c.poles),
                          numbers_text(c.K));
}

Verdict applies(const Analysis& a) {
  Verdict v;
  v.reasons = canonical_form_failures(a);
  v.applies = v.reasons.empty();
  if (!v.applies) return v;
  const std::string A_cl = closed_loop_text(a.canonical);
  set_exactness(v, a.canonical,
                {"the bracket conditions hold and l(u, y) is closed-form",
                 "no bracket condition is refuted and l(u, y) is closed-form",
                 "the error dynamics in z are exactly linear",
                 "rigorous: the error z - zh obeys e' = (" + A_cl +
                     ") e exactly (brackets, T and "
                     "l(u, y) proved symbolically)",
                 "partial (numeric): e' = (" + A_cl +
                     ") e exactly only if what is numerically "
                     "zero is zero"});
  return v;
}

// After an output transformation the form, and so every function above, reads y~ = psi(y):
// the measured y enters through psi in each function that takes the outputs.
void observe_through_psi(const Analysis& a, ObserverSpec& s) {
  const Analysis::OutputTransformation& t = *a.output_transformation;
  GiNaC::exmap through;
  for (std::size_t i = 0; i < t.y.size(); ++i) through[t.y[i]] = t.psi[i];
  for (auto& f : s.functions) {
    const bool reads_y = std::any_of(f.args.begin(), f.args.end(), [](const FunctionArg& g) {
      return g.kind == FunctionArg::Kind::output;
    });
    if (!reads_y) continue;
    for (auto& e : f.outputs) e = e.subs(through);
    for (auto& l : f.lets) l.value = l.value.subs(through);
  }
  s.description.push_back(
      fmt::format("Output transformation: the form is for y~ = psi(y) = [{}]; the step applies psi "
                  "to the measured y ({})",
                  fmt::join(to_strings(t.psi), ", "), t.how));
}

ObserverSpec build(const Analysis& a, const DesignOptions& o) {
  const Verdict v = applies(a);
  if (!v.applies)
    throw UserError(SourceLoc{a.model.file, 0, 0},
                    "method 'canonical' does not apply: " + v.text());
  const Choices c = choose(a, o);
  ObserverSpec s;
  s.method = "canonical";
  s.class_suffix = "Canonical";
  s.state_size = a.model.n();
  s.params = runtime_params(a.model);
  s.functions = model_functions(a.model);
  add_canonical_maps(a, c, s);
  if (c.realisation == Realisation::z)
    build_z_realisation(a, c, s);
  else
    build_x_realisation(a, c, s);
  describe(a, c, s);
  if (a.output_transformation) observe_through_psi(a, s);
  return s;
}

}  // namespace

Design canonical_design() {
  Design d;
  d.name = "canonical";
  d.summary = "Luenberger observer in observer canonical form (seed 003; error exactly linear)";
  d.options = {
      {"poles",
       "error poles, comma-separated negative reals (canonical: of A - K e_n^T; high-gain: of A "
       "- K C, scaled by theta)",
       "-2, -2.5, -3, ..."},
      {"realisation", "canonical observer realisation: z or x", "z when T^-1 is closed-form"},
      {"integrator", "canonical z realisation: exact (zero-order-hold Phi, Gamma) or rk4",
       "exact"}};
  d.plan = stateless_plan<applies, build>;
  return d;
}

}  // namespace obsynth
