#include "designs/extended_linearization.hpp"

#include <fmt/format.h>

#include <cmath>
#include <limits>
#include <map>
#include <set>

#include "analysis/observability.hpp"
#include "designs/design_helpers.hpp"
#include "designs/options.hpp"
#include "front/fresh_names.hpp"
#include "symbolic/expr_print.hpp"
#include "symbolic/integrate.hpp"
#include "symbolic/symbolic.hpp"
#include "symbolic/zero_test.hpp"

namespace obsynth {

using GiNaC::ex;
using GiNaC::numeric;

namespace {

// The symbolic construction's cost grows with the size of its expressions, not with n as such
// (a linear chain of 8 states takes milliseconds; constructed rational chains took 0.2 s at
// n = 5, 4 s at n = 6, minutes at n = 7). Two deterministic budgets, in expression nodes
// (symbolic/symbolic.hpp expression_size), bound it:
// - the closed-form family is abandoned (for its series) once its solution holds more than
//   kFamilyNodes nodes (chain7: 8000 nodes, 35 s; chain6: 1550 nodes, 0.8 s);
// - the Ackermann gain schedule (a symbolic inverse of the n x n observability matrix along
//   the family) is not attempted when A_eps holds more than kJacobianNodes nodes (chain6
//   closed: 12000 nodes, 1.6 s; chain6 series: 30000, 5 s; chain7 series: 77000, 48 s).
// - functions nested more than kNesting deep (sin(x - sin(x)/10) is 2 deep) make the zero
//   test's rewrite and the integrator blow up (an 8-state chain with a sine in every equation:
//   minutes): such a closed-form family is taken as its series, and such a c_i(eps) is not
//   integrated in closed form (its series injection instead).
constexpr std::size_t kFamilyNodes = 4000;
constexpr std::size_t kJacobianNodes = 20000;
constexpr std::size_t kObservabilityNodes = 20000;
constexpr int kNesting = 2;

// Depth of nested function calls (sin, exp, ...; powers and products do not count).
int function_depth(const ex& e) {
  int d = 0;
  for (std::size_t i = 0; i < e.nops(); ++i) d = std::max(d, function_depth(e.op(i)));
  return GiNaC::is_a<GiNaC::function>(e) ? d + 1 : d;
}
constexpr int kDefaultOrder = 6;
constexpr double kTiny = 1e-12;

// Free parameters at their runtime defaults (the centre of their boxes).
GiNaC::exmap param_point(const Model& m) {
  GiNaC::exmap pt;
  for (const auto& p : runtime_params(m)) pt[p.symbol] = p.default_value;
  return pt;
}

double value_at(const ex& e, const GiNaC::exmap& pt) {
  try {
    const ex v = GiNaC::evalf(e.subs(pt, GiNaC::subs_options::no_pattern));
    if (GiNaC::is_a<numeric>(v) && GiNaC::ex_to<numeric>(v).is_real())
      return GiNaC::ex_to<numeric>(v).to_double();
  } catch (const std::exception&) {
  }
  return std::numeric_limits<double>::quiet_NaN();
}

std::string poles_list(const std::vector<numeric>& v) {
  std::vector<std::string> s;
  for (const auto& q : v) s.push_back(to_string(ex(q)));
  return fmt::format("{}", fmt::join(s, ", "));
}

// NaN (a value undefined or complex at the base point) and infinity are said in words, never
// printed as numbers.
std::string num_text(double v) {
  if (std::isnan(v)) return "not a real number (the model is undefined or complex there)";
  if (std::isinf(v)) return "infinite (a pole there)";
  return fmt::format("{:.6g}", v);
}

// dy_eps/deps: one number, or a list for p outputs.
std::string slopes_text(const std::vector<double>& v) {
  if (v.size() == 1) return num_text(v[0]);
  std::vector<std::string> s;
  for (double x : v) s.push_back(num_text(x));
  return fmt::format("[{}]", fmt::join(s, ", "));
}

// Entry by entry: to_string orders each entry deterministically, GiNaC's matrix printing does not.
std::string vec_text(const ExVec& v) {
  return fmt::format("[{}]", fmt::join(to_strings(v), ", "));
}

// The Taylor polynomial of e in eps up to eps^order (inclusive).
ex taylor(const ex& e, const GiNaC::symbol& eps, int order) {
  const ex s = e.series(eps == 0, order + 1);
  ex p = GiNaC::series_to_poly(s).expand();
  ex out = 0;
  for (int k = 0; k <= order; ++k) out += p.coeff(eps, k) * GiNaC::pow(eps, k);
  return out;
}

struct Problem {
  ExVec F;                              // f + g with the other inputs at u0
  ExVec H;                              // the outputs
  std::vector<GiNaC::symbol> unknowns;  // states, then the first input
  ExVec equations;                      // F, h_k - y0_k - eps
  GiNaC::exmap base;                    // unknowns -> base values
};

// Solve the family one unknown at a time; nullopt when some step is not linear with a
// coefficient nonzero at the base point.
// too_large: the solution's size in nodes when it was abandoned past kFamilyNodes.
std::optional<GiNaC::exmap> closed_family(const Model& m, const Problem& P,
                                          const GiNaC::symbol& eps, const GiNaC::exmap& params,
                                          std::size_t& too_large, int& too_deep) {
  GiNaC::exmap sol;
  std::vector<bool> used(P.equations.size(), false);
  std::set<unsigned> solved;
  bool progress = true;
  while (progress && sol.size() < P.unknowns.size()) {
    progress = false;
    for (std::size_t i = 0; i < P.equations.size() && !progress; ++i) {
      if (used[i]) continue;
      const ex e = simplify(P.equations[i].subs(sol, GiNaC::subs_options::no_pattern));
      for (std::size_t k = 0; k < P.unknowns.size() && !progress; ++k) {
        const GiNaC::symbol& z = P.unknowns[k];
        if (sol.count(z) || !e.has(z)) continue;
        const ex d = simplify(e.diff(z));
        bool free = true;
        for (const auto& w : P.unknowns)
          if (!sol.count(w) && d.has(w)) free = false;
        if (!free) continue;
        GiNaC::exmap at0 = params;
        at0[eps] = 0;
        const double dv = value_at(d, at0);
        if (!std::isfinite(dv) || std::fabs(dv) < kTiny) continue;
        const ex rest = e.subs(z == 0);
        const ex value = simplify(-rest / d);
        std::size_t nodes = expression_size(value);
        for (auto& kv : sol) {
          kv.second = simplify(kv.second.subs(z == value));
          nodes += expression_size(kv.second);
        }
        sol[z] = value;
        used[i] = true;
        progress = true;
        if (nodes > kFamilyNodes) {
          too_large = nodes;
          return std::nullopt;
        }
      }
    }
  }
  if (sol.size() < P.unknowns.size()) return std::nullopt;
  for (const auto& kv : sol)
    if (function_depth(kv.second) > kNesting) {
      too_deep = function_depth(kv.second);
      return std::nullopt;
    }
  // Verify: every equation vanishes identically in eps on the family.
  SampleBoxes boxes = m.sample_boxes();
  boxes.by_name[eps.get_name()] = Interval{numeric(-1, 20), numeric(1, 20)};
  for (const auto& e : P.equations)
    if (!is_zero_verdict(zero_test(e.subs(sol, GiNaC::subs_options::no_pattern), boxes)))
      return std::nullopt;
  (void)m;
  return sol;
}

// Newton on truncated power series with the Jacobian at the base point fixed: each iteration
// gains one order, `order` iterations give the Taylor polynomial of the family to eps^order.
std::optional<GiNaC::exmap> series_family(const Problem& P, const GiNaC::symbol& eps, int order,
                                          std::string& why) {
  const unsigned d = static_cast<unsigned>(P.unknowns.size());
  GiNaC::matrix J(d, d);
  for (unsigned i = 0; i < d; ++i)
    for (unsigned j = 0; j < d; ++j)
      J(i, j) = P.equations[i]
                    .diff(P.unknowns[j])
                    .subs(P.base, GiNaC::subs_options::no_pattern)
                    .subs(eps == 0);
  const ex det = simplify(J.determinant());
  if (det.is_zero()) {
    why = "the Jacobian of (f + g, h) in (x, u) is singular at the base point";
    return std::nullopt;
  }
  const GiNaC::matrix Ji = J.inverse();
  std::vector<ex> z(d);
  for (unsigned j = 0; j < d; ++j) z[j] = P.base.at(P.unknowns[j]);
  for (int it = 0; it < order; ++it) {
    GiNaC::exmap cur;
    for (unsigned j = 0; j < d; ++j) cur[P.unknowns[j]] = z[j];
    std::vector<ex> r(d);
    for (unsigned i = 0; i < d; ++i)
      r[i] = taylor(P.equations[i].subs(cur, GiNaC::subs_options::no_pattern), eps, order);
    for (unsigned j = 0; j < d; ++j) {
      ex acc = z[j];
      for (unsigned i = 0; i < d; ++i) acc -= Ji(j, i) * r[i];
      z[j] = taylor(GiNaC::expand(acc), eps, order);
    }
  }
  GiNaC::exmap sol;
  for (unsigned j = 0; j < d; ++j) sol[P.unknowns[j]] = z[j];
  for (const auto& e : P.equations) {
    const ex res = taylor(e.subs(sol, GiNaC::subs_options::no_pattern), eps, order);
    if (!GiNaC::normal(res).is_zero()) {
      why = fmt::format("the series of the family does not converge to order {} (residual {})",
                        order, to_string(res));
      return std::nullopt;
    }
  }
  return sol;
}

int order_option(const DesignOptions& o, const std::string& name, int dflt) {
  const auto v = real_option(o, name);
  if (!v) return dflt;
  if (!v->is_integer() || *v < 1 || *v > 20)
    throw UserError(SourceLoc{},
                    fmt::format("--{}: expected an integer in 1..20, got {}", name, to_string(*v)));
  return v->to_int();
}

// The --el-* choices besides the poles and the base point.
struct RunOptions {
  std::string injection, family;  // modes
  int order = kDefaultOrder, family_order = kDefaultOrder;
};

// Reads the options first: bad options are errors whatever the model. The poles go into r
// (default -1, ..., -n).
RunOptions read_options(const DesignOptions& o, std::size_t n, ExtendedLinearization& r) {
  r.poles = real_list_option(o, "el-poles");
  r.poles_given = !r.poles.empty();
  if (r.poles_given) {
    if (r.poles.size() != n)
      throw UserError(SourceLoc{},
                      fmt::format("--el-poles: {} poles given, the model has n = {} states",
                                  r.poles.size(), n));
    for (const auto& q : r.poles)
      if (!q.is_negative())
        throw UserError(SourceLoc{}, fmt::format("--el-poles: pole {} is not negative (the error "
                                                 "dynamics must be stable)",
                                                 to_string(q)));
  } else {
    for (std::size_t k = 0; k < n; ++k) r.poles.push_back(-numeric(static_cast<long>(k + 1)));
  }
  RunOptions ro;
  ro.injection = choice_option(o, "el-injection", {"auto", "closed", "series"}).value_or("auto");
  ro.family = choice_option(o, "el-family", {"auto", "series"}).value_or("auto");
  ro.order = order_option(o, "el-order", kDefaultOrder);
  ro.family_order = order_option(o, "el-family-order", ro.order);
  return ro;
}

// The model shapes the construction handles (an input, y = h(x)); false with the failure in r
// otherwise.
bool supported(const Model& m, ExtendedLinearization& r) {
  if (m.m() == 0) {
    r.failures.push_back(
        "the model has no input: there is no family of equilibria x_eps, u_eps "
        "(seed 001 §5 needs a controlled system)");
    return false;
  }
  if (m.feedthrough()) {
    r.failures.push_back(
        "the output depends on the input (y = h(x, u)); the seed assumes y = h(x)");
    return false;
  }
  return true;
}

// The base point: --el-base (x0 and the first input), else the origin with the nominal input;
// the other inputs held at u0 (into other_inputs). Fills r.x0, r.u0, r.y0 and P but for its
// equations.
Problem base_problem(const Model& m, const DesignOptions& o, ExtendedLinearization& r,
                     GiNaC::exmap& other_inputs) {
  const std::size_t n = m.n();
  const std::vector<numeric> base = real_list_option(o, "el-base");
  if (!base.empty() && base.size() != n + 1)
    throw UserError(SourceLoc{}, fmt::format("--el-base: expected n + 1 = {} numbers (the states, "
                                             "then the first input), got {}",
                                             n + 1, base.size()));
  Problem P;
  for (std::size_t j = 0; j < m.m(); ++j) {
    const numeric uj = j == 0 && !base.empty() ? base[n]
                       : j < m.nominal.size()  ? m.nominal[j]
                                               : numeric(0);
    r.u0.push_back(uj);
    if (j > 0) other_inputs[m.inputs[j]] = uj;
  }
  for (const auto& e : m.field())
    P.F.push_back(e.subs(other_inputs, GiNaC::subs_options::no_pattern));
  P.H = m.h;
  for (std::size_t i = 0; i < n; ++i) {
    P.unknowns.push_back(m.states[i]);
    r.x0.push_back(base.empty() ? numeric(0) : base[i]);
    P.base[m.states[i]] = r.x0.back();
  }
  P.unknowns.push_back(m.inputs[0]);
  P.base[m.inputs[0]] = r.u0[0];
  for (const auto& h : P.H)
    r.y0.push_back(simplify(h.subs(P.base, GiNaC::subs_options::no_pattern)));
  return P;
}

// Whether the base point is an equilibrium (F = 0 there, proved on the model's boxes);
// false with the failure in r otherwise.
bool at_equilibrium(const Model& m, const Problem& P, ExtendedLinearization& r) {
  SampleBoxes boxes = m.sample_boxes();
  ExVec F0;
  bool equilibrium = true;
  for (const auto& e : P.F) {
    F0.push_back(simplify(e.subs(P.base, GiNaC::subs_options::no_pattern)));
    if (!is_zero_verdict(zero_test(F0.back(), boxes))) equilibrium = false;
  }
  if (!equilibrium)
    r.failures.push_back(fmt::format(
        "the base point x0 = ({}) with u = {} is not an equilibrium: f(x0) + g(x0, u0) = {} (seed "
        "001 eq. 27 needs f(0, 0) = 0; give an equilibrium with --el-base)",
        poles_list(r.x0), to_string(ex(r.u0[0])), vec_text(F0)));
  return equilibrium;
}

// The failures of constraints (i)-(iii) into r.
void constraint_failures(bool c1, bool c2, bool c3, const std::string& obs_text,
                         ExtendedLinearization& r) {
  if (!c1)
    r.failures.push_back(fmt::format("constraint (i) fails: det(d(f+g)/dx) at the base point = {}",
                                     num_text(r.det_A0)));
  if (!c2)
    r.failures.push_back(
        fmt::format("constraint (ii) fails: (A0, H0) not observable, {}", obs_text));
  if (c1 && !c3)
    r.failures.push_back(fmt::format("constraint (iii) fails: dy_eps/deps = -H0 A0^-1 B0 = {}",
                                     slopes_text(r.output_slopes)));
}

// (A0, H0)'s observability at the parameter point: the determinant of its observability matrix
// for one output, else the rank of the stacked [H0; H0 A0; ...] (exact when every entry is
// rational); the text names the figure.
std::size_t observability_rank(const GiNaC::matrix& A0, const GiNaC::matrix& H0,
                               const GiNaC::exmap& params, std::string& text) {
  const unsigned n = A0.rows(), p = H0.rows();
  if (p == 1) {
    const double det = value_at(linear_observability_matrix(A0, H0).determinant(), params);
    const std::size_t rank = std::isfinite(det) && std::fabs(det) > kTiny ? n : n - 1;
    text = fmt::format("det of its observability matrix = {}", num_text(det));
    return rank;
  }
  std::vector<std::vector<numeric>> rows;
  bool exact = true;
  GiNaC::matrix row = H0;
  for (unsigned k = 0; k < n; ++k) {
    for (unsigned i = 0; i < p; ++i) {
      rows.emplace_back();
      for (unsigned j = 0; j < n; ++j) {
        const ex e = row(i, j).subs(params, GiNaC::subs_options::no_pattern);
        if (GiNaC::is_a<numeric>(e) && GiNaC::ex_to<numeric>(e).is_rational()) {
          rows.back().push_back(GiNaC::ex_to<numeric>(e));
        } else {
          exact = false;
          const double v = value_at(e, params);
          rows.back().push_back(std::isfinite(v) ? numeric(v) : numeric(0));
        }
      }
    }
    row = row.mul(A0);
  }
  const std::size_t rank = numeric_rank(rows, exact);
  text = fmt::format("rank of [H0; H0 A0; ...; H0 A0^{}] = {} of n = {}{}", n - 1, rank, n,
                     exact ? "" : " (floating point)");
  return rank;
}

// The linearisation at the base point and constraints (i) det A0 != 0, (ii) (A0, H0)
// observable, (iii) dy_eps/deps != 0 for some output (the first such output parametrises the
// family: r.level_output), with notes; false when one fails.
bool check_constraints(const Model& m, const Problem& P, const GiNaC::exmap& params,
                       ExtendedLinearization& r) {
  const std::size_t n = m.n();
  const unsigned p = static_cast<unsigned>(P.H.size());
  GiNaC::matrix A0(static_cast<unsigned>(n), static_cast<unsigned>(n)),
      B0(static_cast<unsigned>(n), 1), H0(p, static_cast<unsigned>(n));
  for (unsigned i = 0; i < n; ++i) {
    for (unsigned j = 0; j < n; ++j)
      A0(i, j) = P.F[i].diff(m.states[j]).subs(P.base, GiNaC::subs_options::no_pattern);
    B0(i, 0) = P.F[i].diff(m.inputs[0]).subs(P.base, GiNaC::subs_options::no_pattern);
    for (unsigned l = 0; l < p; ++l)
      H0(l, i) = P.H[l].diff(m.states[i]).subs(P.base, GiNaC::subs_options::no_pattern);
  }
  r.det_A0 = value_at(A0.determinant(), params);
  std::string obs_text;
  r.obs_rank = observability_rank(A0, H0, params, obs_text);
  const std::string at_params =
      params.empty() ? std::string() : " (free parameters at the centre of their boxes)";
  const bool c1 = std::isfinite(r.det_A0) && std::fabs(r.det_A0) > kTiny;
  const bool c2 = r.obs_rank == n;
  r.notes.push_back(fmt::format(
      "base point x0 = ({}), u0 = {}, y0 = h(x0) = {}; A0 = d(f+g)/dx = {}, "
      "B0 = d(f+g)/du = {}, H0 = dh/dx = {}{}",
      poles_list(r.x0), to_string(ex(r.u0[0])), p == 1 ? to_string(r.y0[0]) : vec_text(r.y0),
      matrix_text(A0), matrix_text(B0), matrix_text(H0), at_params));
  r.output_slopes.assign(p, std::numeric_limits<double>::quiet_NaN());
  if (c1) {
    const GiNaC::matrix slopes = H0.mul(A0.inverse()).mul(B0);
    for (unsigned l = 0; l < p; ++l) r.output_slopes[l] = value_at(slopes(l, 0) * -1, params);
  }
  bool c3 = false;
  for (unsigned l = 0; l < p && c1 && !c3; ++l)
    if (std::isfinite(r.output_slopes[l]) && std::fabs(r.output_slopes[l]) > kTiny) {
      c3 = true;
      r.level_output = l;
    }
  r.dy_deps = r.output_slopes[r.level_output];
  r.notes.push_back(
      fmt::format("constraint (i) {}: det A0 = {}", c1 ? "holds" : "fails", num_text(r.det_A0)));
  r.notes.push_back(
      p == 1 ? fmt::format("constraint (ii) {}: det O(A0, H0) = {} (rank {} of n = {})",
                           c2 ? "holds" : "fails", obs_text.substr(obs_text.find("= ") + 2),
                           c2 ? n : r.obs_rank, n)
             : fmt::format("constraint (ii) {}: {}", c2 ? "holds" : "fails", obs_text));
  r.notes.push_back(fmt::format(
      "constraint (iii) {}: dy_eps/deps = -H0 A0^-1 B0 = {}{}", c3 ? "holds" : "fails",
      c1 ? slopes_text(r.output_slopes) : std::string("undefined (A0 singular)"),
      c3 && p > 1 ? fmt::format("; the family is parametrised by the level of output {} ({})",
                                r.level_output + 1, to_string(P.H[r.level_output]))
                  : std::string()));
  constraint_failures(c1, c2, c3, obs_text, r);
  return r.failures.empty();
}

// The equilibrium family x_eps, u_eps: in closed form when the mode allows and it is found,
// else as a Taylor series; nullopt with the failure in r when neither exists.
std::optional<GiNaC::exmap> equilibrium_family(const Model& m, const Problem& P,
                                               const GiNaC::exmap& params, const RunOptions& ro,
                                               ExtendedLinearization& r) {
  std::optional<GiNaC::exmap> fam;
  std::string why;
  std::size_t too_large = 0;
  int too_deep = 0;
  if (ro.family == "auto") fam = closed_family(m, P, r.eps, params, too_large, too_deep);
  if (too_deep > 0)
    r.notes.push_back(fmt::format(
        "the closed-form equilibrium family was abandoned for its series: it nests functions {} "
        "deep (budget {})",
        too_deep, kNesting));
  if (too_large > 0)
    r.notes.push_back(fmt::format(
        "the closed-form equilibrium family was abandoned for its series: its expressions grew "
        "to {} nodes (budget {})",
        too_large, kFamilyNodes));
  if (fam) {
    r.family_closed = true;
  } else {
    fam = series_family(P, r.eps, ro.family_order, why);
    if (!fam) {
      r.failures.push_back("no equilibrium family: " + why);
      return std::nullopt;
    }
    r.family_order = ro.family_order;
  }
  for (const auto& x : m.states) r.x_eps.push_back(fam->at(x));
  r.u_eps = fam->at(m.inputs[0]);
  return fam;
}

// A_eps and H_eps: the Jacobians of F and h along the family.
struct FamilyJacobians {
  GiNaC::matrix A, H;
};

FamilyJacobians family_jacobians(const Model& m, const Problem& P, const GiNaC::exmap& on_family,
                                 bool closed) {
  const unsigned n = static_cast<unsigned>(m.n());
  const unsigned p = static_cast<unsigned>(P.H.size());
  FamilyJacobians j{GiNaC::matrix(n, n), GiNaC::matrix(p, n)};
  // Series family: entries stay unsimplified (the Taylor expansion of the gain does the work).
  auto tidy = [&](const ex& e) { return closed ? simplify(e) : e; };
  for (unsigned i = 0; i < n; ++i) {
    for (unsigned k = 0; k < n; ++k)
      j.A(i, k) = tidy(P.F[i].diff(m.states[k]).subs(on_family, GiNaC::subs_options::no_pattern));
    for (unsigned l = 0; l < p; ++l)
      j.H(l, i) = tidy(P.H[l].diff(m.states[i]).subs(on_family, GiNaC::subs_options::no_pattern));
  }
  return j;
}

// The single-output pair (A_eps - L0 H_eps, w^T H_eps) of the reduction C^T = L0 + c w^T.
struct ReducedPair {
  GiNaC::matrix A, h;
};

ReducedPair reduced_pair(const FamilyJacobians& J, const std::vector<std::vector<numeric>>& L0,
                         const std::vector<numeric>& w) {
  const unsigned n = J.A.rows(), p = J.H.rows();
  ReducedPair r{J.A, GiNaC::matrix(1, n)};
  for (unsigned j = 0; j < n; ++j) {
    ex hj = 0;
    for (unsigned l = 0; l < p; ++l) hj += w[l] * J.H(l, j);
    r.h(0, j) = hj;
    for (unsigned i = 0; i < n; ++i)
      for (unsigned l = 0; l < p; ++l)
        if (!L0[i][l].is_zero()) r.A(i, j) = r.A(i, j) - L0[i][l] * J.H(l, j);
  }
  return r;
}

// The candidates (L0, w) of the reduction, in order: L0 = 0 with one output (the family's own
// first), then the sum of the outputs, then pre-gains with entries in {-1, 0, 1} from a fixed
// sequence (A0 - L0 H0 is cyclic for almost every L0). One candidate (0, 1) for p = 1.
std::vector<std::pair<std::vector<std::vector<numeric>>, std::vector<numeric>>>
reduction_candidates(unsigned n, unsigned p, std::size_t first) {
  using L = std::vector<std::vector<numeric>>;
  const L zero(n, std::vector<numeric>(p, 0));
  std::vector<std::pair<L, std::vector<numeric>>> out;
  auto unit = [&](std::size_t k) {
    std::vector<numeric> w(p, 0);
    w[k] = 1;
    return w;
  };
  out.push_back({zero, unit(first)});
  for (std::size_t k = 0; k < p; ++k)
    if (k != first) out.push_back({zero, unit(k)});
  if (p == 1) return out;
  out.push_back({zero, std::vector<numeric>(p, 1)});
  unsigned seed = 12345;  // a fixed linear congruential sequence: deterministic output
  for (int attempt = 0; attempt < 6; ++attempt) {
    L l0 = zero;
    for (auto& row : l0)
      for (auto& e : row) {
        seed = seed * 1103515245u + 12345u;
        e = static_cast<long>((seed >> 16) % 3) - 1;
      }
    out.push_back({l0, unit(first)});
  }
  return out;
}

std::string combination_text(const std::vector<numeric>& w) {
  std::vector<std::string> s;
  for (const auto& x : w) s.push_back(to_string(ex(x)));
  return fmt::format("({})", fmt::join(s, ", "));
}

std::string pre_gain_text(const std::vector<std::vector<numeric>>& L0) {
  std::vector<std::string> rows;
  for (const auto& r : L0) rows.push_back(combination_text(r));
  return fmt::format("[{}]", fmt::join(rows, ", "));
}

// The first candidate (L0, w) whose reduced pair is observable at the base point (eps = 0,
// parameters at their centre) into r.pre_gain, r.combination; false with the failure in r.
bool choose_reduction(const FamilyJacobians& J, const GiNaC::exmap& params,
                      ExtendedLinearization& r) {
  const unsigned n = J.A.rows(), p = J.H.rows();
  GiNaC::exmap at0 = params;
  at0[r.eps] = 0;
  for (const auto& [L0, w] : reduction_candidates(n, p, r.level_output)) {
    const ReducedPair red = reduced_pair(J, L0, w);
    const GiNaC::matrix A0 = GiNaC::ex_to<GiNaC::matrix>(red.A.subs(at0));
    const GiNaC::matrix h0 = GiNaC::ex_to<GiNaC::matrix>(red.h.subs(at0));
    const double det = value_at(linear_observability_matrix(A0, h0).determinant(), params);
    if (!std::isfinite(det) || std::fabs(det) <= kTiny) continue;
    r.pre_gain = L0;
    r.combination = w;
    if (p > 1)
      r.notes.push_back(fmt::format(
          "gain reduction C^T = L0 + c(eps) w^T: w = {}, L0 = {}; det O(A0 - L0 H0, w^T H0) = {}",
          combination_text(w), pre_gain_text(L0), num_text(det)));
    return true;
  }
  r.failures.push_back(
      "no reduction C^T = L0 + c(eps) w^T to one output was found: (A0 - L0 H0, w^T H0) is not "
      "observable for any output, the sum of the outputs, or six pre-gains L0 (A0 not cyclic)");
  return false;
}

// The gain schedule C(eps)^T = L0 + c(eps) w^T, c(eps) by Ackermann's formula on the reduced
// pair along the family, into r.c_eps and r.gain (simplified, or Taylor polynomials to
// eps^(m-1)); false with the failure in r when a budget stops it or O_eps is singular.
bool gain_schedule(const FamilyJacobians& J, const GiNaC::exmap& params, int order,
                   ExtendedLinearization& r) {
  const unsigned n = J.A.rows(), p = J.H.rows();
  std::size_t nodes = 0;
  for (unsigned i = 0; i < n; ++i) {
    for (unsigned l = 0; l < p; ++l) nodes += expression_size(J.H(l, i));
    for (unsigned j = 0; j < n; ++j) nodes += expression_size(J.A(i, j));
  }
  if (nodes > kJacobianNodes) {
    r.failures.push_back(fmt::format(
        "the symbolic Ackermann gain schedule is not attempted: A_eps and H_eps along the {} "
        "family hold {} expression nodes, past the budget of {} (its cost grows with their "
        "size: minutes beyond it); a simpler model, or fewer states, keeps it in budget",
        r.family_closed ? "closed-form" : fmt::format("series (order {})", r.family_order), nodes,
        kJacobianNodes));
    return false;
  }
  if (!choose_reduction(J, params, r)) return false;
  const ReducedPair red = reduced_pair(J, r.pre_gain, r.combination);
  GiNaC::matrix en(n, 1);
  en(n - 1, 0) = 1;
  const GiNaC::matrix O = linear_observability_matrix(red.A, red.h);
  // O's rows H A^k grow with k: the inverse's cost follows O's size, not A's (nested chain
  // family: 3002 nodes 0.7 s, 58710 nodes 2 s, 200971 nodes 13 s at n = 5, 7, 8).
  std::size_t o_nodes = 0;
  for (unsigned i = 0; i < n; ++i)
    for (unsigned j = 0; j < n; ++j) o_nodes += expression_size(O(i, j));
  if (o_nodes > kObservabilityNodes) {
    r.failures.push_back(fmt::format(
        "the symbolic Ackermann gain schedule is not attempted: the observability matrix [H; H A; "
        "...] along the family holds {} expression nodes, past the budget of {} (its inverse "
        "costs seconds to minutes beyond it); a simpler model, or fewer states, keeps it in "
        "budget",
        o_nodes, kObservabilityNodes));
    return false;
  }
  GiNaC::matrix v;
  try {
    v = O.inverse().mul(en);
  } catch (const std::exception& e) {
    r.failures.push_back(std::string("the observability matrix along the family is singular: ") +
                         e.what());
    return false;
  }
  GiNaC::matrix pA = GiNaC::ex_to<GiNaC::matrix>(GiNaC::unit_matrix(n));
  for (const auto& q : r.poles)
    pA = pA.mul(red.A.sub(GiNaC::ex_to<GiNaC::matrix>(GiNaC::unit_matrix(n)).mul_scalar(q)));
  const GiNaC::matrix c = pA.mul(v);
  for (unsigned i = 0; i < n; ++i) {
    const ex ci =
        r.family_closed ? simplify(c(i, 0)) : taylor(c(i, 0), r.eps, std::max(0, order - 1));
    r.c_eps.push_back(ci);
  }
  r.gain.assign(p, ExVec{});
  for (unsigned l = 0; l < p; ++l)
    for (unsigned i = 0; i < n; ++i)
      r.gain[l].push_back(r.combination[l].is_zero()
                              ? ex(r.pre_gain[i][l])
                              : ex(r.pre_gain[i][l]) + r.combination[l] * r.c_eps[i]);
  return true;
}

// Self-check: det(lambda I - A_eps + c(eps) H_eps) = prod (lambda - pole), identically in eps
// (closed form) or up to eps^(m-1) (series); false with the failure in r otherwise.
bool check_charpoly(const Model& m, const FamilyJacobians& J, int order, ExtendedLinearization& r) {
  const unsigned n = J.A.rows();
  const GiNaC::symbol lambda("lambda");
  GiNaC::matrix M(n, n);
  for (unsigned i = 0; i < n; ++i)
    for (unsigned j = 0; j < n; ++j) {
      M(i, j) = J.A(i, j);
      for (unsigned l = 0; l < J.H.rows(); ++l) M(i, j) = M(i, j) - r.gain[l][i] * J.H(l, j);
    }
  ex want = 1;
  for (const auto& q : r.poles) want *= lambda - q;
  // GiNaC's charpoly is det(M - lambda I) = (-1)^n det(lambda I - M).
  const ex sign = n % 2 == 0 ? 1 : -1;
  const ex diff = GiNaC::expand(sign * M.charpoly(lambda) - want);
  bool ok = true;
  SampleBoxes eboxes = m.sample_boxes();
  eboxes.by_name[r.eps.get_name()] = Interval{numeric(-1, 20), numeric(1, 20)};
  for (unsigned k = 0; k < n && ok; ++k) {
    const ex coef = diff.coeff(lambda, static_cast<int>(k));
    ok = r.family_closed ? is_zero_verdict(zero_test(coef, eboxes))
                         : GiNaC::normal(taylor(coef, r.eps, std::max(0, order - 1))).is_zero();
  }
  if (!ok) {
    r.failures.push_back(
        "internal check failed: the characteristic polynomial of A_eps - c(eps) H_eps "
        "is not the prescribed one");
    return false;
  }
  r.notes.push_back(
      r.family_closed
          ? "checked: det(lambda I - A_eps + c(eps) H_eps) = prod (lambda - pole) identically in "
            "eps"
          : fmt::format("checked: det(lambda I - A_eps + c(eps) H_eps) = prod (lambda - pole) + "
                        "O(eps^{})",
                        order));
  return true;
}

// The family's output levels y_j,eps = h_j(x_eps) (absolute), one per output (y_k,eps = y0_k +
// eps).
ExVec family_outputs(const Model& m, const ExtendedLinearization& r) {
  GiNaC::exmap on;
  for (std::size_t i = 0; i < m.n(); ++i) on[m.states[i]] = r.x_eps[i];
  on[m.inputs[0]] = r.u_eps;
  for (std::size_t j = 1; j < m.m(); ++j) on[m.inputs[j]] = r.u0[j];
  ExVec out;
  for (std::size_t l = 0; l < m.p(); ++l)
    out.push_back(l == r.level_output ? r.y0[l] + r.eps
                                      : ex(m.h[l].subs(on, GiNaC::subs_options::no_pattern)));
  return out;
}

// Component i of the integrand of G(s) = int_0^s C(e)^T dy_e/de de (eq. 39):
// c_ki + sum_{j != k} c_ji d ybar_j/deps (y_k,eps = y0_k + eps).
ex integrand(const ExtendedLinearization& r, const ExVec& ybar, std::size_t i) {
  ex e = r.gain[r.level_output][i];
  for (std::size_t l = 0; l < r.gain.size(); ++l)
    if (l != r.level_output && !r.gain[l][i].is_zero()) e += r.gain[l][i] * ybar[l].diff(r.eps);
  return e;
}

// The injection k(y) = G(s) + sum_{j != k} c_j(s) (y_j - ybar_j(s)), s = y_k - y0_k (eq. 40), in
// closed form into r.injection: false with r.injection_reason when the family is a series or an
// antiderivative is missing or undefined at 0.
bool closed_injection(const Model& m, const GiNaC::exmap& params, ExtendedLinearization& r) {
  if (!r.family_closed) {
    r.injection_reason = fmt::format(
        "the equilibrium family is a series (order {}), so c(eps) is too", r.family_order);
    return false;
  }
  const std::size_t k = r.level_output;
  const ex shift = r.y[k] - r.y0[k];
  const GiNaC::symbol& eps = r.eps;
  const ExVec ybar = family_outputs(m, r);
  ExVec out;
  for (unsigned i = 0; i < m.n(); ++i) {
    const ex c = integrand(r, ybar, i);
    if (function_depth(c) > kNesting) {
      r.injection_reason = fmt::format(
          "c_{}(eps) nests functions {} deep (budget {}): not integrated in closed form", i + 1,
          function_depth(c), kNesting);
      return false;
    }
    const Integral I = integrate(c, eps);
    if (!I.value) {
      r.injection_reason = fmt::format("no antiderivative of c_{}(eps) = {} found: {}", i + 1,
                                       to_string(c), I.reason);
      return false;
    }
    const ex at0 = I.value->subs(eps == 0);
    GiNaC::exmap z0 = params;
    if (!std::isfinite(value_at(at0, z0))) {
      r.injection_reason = fmt::format("the antiderivative of c_{} is undefined at eps = 0", i + 1);
      return false;
    }
    ex ki = I.value->subs(eps == shift) - at0;
    for (std::size_t l = 0; l < m.p(); ++l)
      if (l != k && !r.gain[l][i].is_zero())
        ki += (r.gain[l][i] * (r.y[l] - ybar[l])).subs(eps == shift);
    out.push_back(simplify(ki));
  }
  r.injection = out;
  return true;
}

// The injection from the Taylor polynomials to eps^(m-1) of G's integrand and of c_j, and to
// eps^m of ybar_j.
void series_injection(const Model& m, int order, ExtendedLinearization& r) {
  const std::size_t k = r.level_output;
  const ex shift = r.y[k] - r.y0[k];
  const ExVec ybar = family_outputs(m, r);
  r.injection_order = order;
  r.injection.clear();
  for (unsigned i = 0; i < m.n(); ++i) {
    const ex ci = taylor(integrand(r, ybar, i), r.eps, order - 1);
    ex ki = 0;
    for (int j = 0; j < order; ++j) ki += ci.coeff(r.eps, j) / (j + 1) * GiNaC::pow(shift, j + 1);
    for (std::size_t l = 0; l < m.p(); ++l)
      if (l != k && !r.gain[l][i].is_zero())
        ki += (taylor(r.gain[l][i], r.eps, order - 1) * (r.y[l] - taylor(ybar[l], r.eps, order)))
                  .subs(r.eps == shift);
    r.injection.push_back(ki);
  }
}

// The injection: closed form unless --el-injection series (an error when closed is demanded
// and not found), else the series.
void injection(const Model& m, const GiNaC::exmap& params, const RunOptions& ro,
               ExtendedLinearization& r) {
  bool closed = false;
  if (ro.injection != "series") {
    closed = closed_injection(m, params, r);
    if (!closed && ro.injection == "closed") {
      r.failures.push_back("--el-injection closed: " + r.injection_reason);
      return;
    }
  } else {
    r.injection_reason = "--el-injection series";
  }
  r.injection_closed = closed;
  if (!closed) series_injection(m, ro.order, r);
}

ExtendedLinearization run(const Model& m, const DesignOptions& o) {
  ExtendedLinearization r;
  const RunOptions ro = read_options(o, m.n(), r);
  if (!supported(m, r)) return r;
  const GiNaC::exmap params = param_point(m);
  GiNaC::exmap other_inputs;
  if (m.p() == 1) {
    r.y = {GiNaC::symbol("y")};
  } else {
    for (std::size_t l = 0; l < m.p(); ++l) r.y.push_back(GiNaC::symbol(fmt::format("y{}", l + 1)));
  }
  Problem P = base_problem(m, o, r, other_inputs);
  if (!at_equilibrium(m, P, r)) return r;
  if (!check_constraints(m, P, params, r)) return r;
  for (const auto& e : P.F) P.equations.push_back(e);
  P.equations.push_back(P.H[r.level_output] - r.y0[r.level_output] - r.eps);

  const std::optional<GiNaC::exmap> fam = equilibrium_family(m, P, params, ro, r);
  if (!fam) return r;
  // Gain schedule by Ackermann's formula on the family, then its self-check.
  GiNaC::exmap on_family = *fam;
  for (const auto& kv : other_inputs) on_family[kv.first] = kv.second;
  const FamilyJacobians J = family_jacobians(m, P, on_family, r.family_closed);
  if (!gain_schedule(J, params, ro.order, r) || !check_charpoly(m, J, ro.order, r)) return r;
  injection(m, params, ro, r);
  return r;
}

std::string poles_text(const std::vector<numeric>& p) {
  std::vector<std::string> s;
  for (const auto& q : p) s.push_back(to_string(ex(q)));
  return fmt::format("{}", fmt::join(s, ", "));
}

std::string family_text(const Model& m, const ExtendedLinearization& r) {
  std::vector<std::string> parts;
  for (std::size_t i = 0; i < m.n(); ++i)
    parts.push_back(fmt::format("{} = {}", m.states[i].get_name(), to_string(r.x_eps[i])));
  parts.push_back(fmt::format("{} = {}", m.inputs[0].get_name(), to_string(r.u_eps)));
  return fmt::format(
      "{} ({})", fmt::join(parts, ", "),
      r.family_closed
          ? "closed form"
          : fmt::format("Taylor polynomial to eps^{}, implicit function theorem", r.family_order));
}

std::string injection_kind(const ExtendedLinearization& r) {
  if (r.injection_closed) return "closed form (eq. 40, integrals by the project's integrator)";
  return fmt::format("series to order m = {} (eq. 42-45; dk/dy(y_eps) = c(eps) + O(eps^{})): {}",
                     r.injection_order, r.injection_order, r.injection_reason);
}

Verdict verdict_of(const Analysis&, const Lazy<ExtendedLinearization>& work) {
  Verdict v;
  const ExtendedLinearization* r = nullptr;
  try {
    r = &work.get();
  } catch (const std::exception& e) {
    v.reasons.push_back(std::string("the design failed: ") + e.what());
    return v;
  }
  if (!r->failures.empty()) {
    v.reasons = r->failures;
    // The base point and the constraints that hold (the failed ones are already listed).
    for (const auto& nt : r->notes)
      if (nt.find(" fails") == std::string::npos) v.reasons.push_back(nt);
    return v;
  }
  v.applies = true;
  v.reasons.push_back(fmt::format(
      "constraints (i)-(iii) hold at the base point (det A0 = {}, (A0, H0) observable, dy_eps/deps "
      "= {}); equilibrium family {}; the linearized error has eigenvalues {} for every eps (local "
      "result near the family); injection {}",
      num_text(r->det_A0), num_text(r->dy_deps),
      r->family_closed ? "in closed form" : "as a series", poles_text(r->poles),
      r->injection_closed ? "in closed form" : "as a series"));
  return v;
}

// The spec without its texts: the injection k(y) and xh' = f + g + k(y) - k(h(xh)), with the
// measured outputs y and yh = h(xh) named apart from the model's names.
ObserverSpec el_skeleton(const Model& m, const ExtendedLinearization& r) {
  const std::size_t n = m.n();
  const std::vector<GiNaC::symbol> y = measurement_symbols(m);
  const std::vector<GiNaC::symbol> yh = m.p() == 1
                                            ? std::vector<GiNaC::symbol>{fresh_symbol(m, "yh")}
                                            : fresh_symbols(m, "yh", m.p());
  GiNaC::exmap to_y, to_yh;
  for (std::size_t l = 0; l < m.p(); ++l) {
    to_y[r.y[l]] = y[l];
    to_yh[r.y[l]] = yh[l];
  }
  ExVec k_y, rhs;
  const ExVec F = m.field();
  for (std::size_t i = 0; i < n; ++i) {
    const ex ki = r.injection[i];
    k_y.push_back(ki.subs(to_y));
    rhs.push_back(F[i] + ki.subs(to_y) - ki.subs(to_yh));
  }
  ObserverSpec spec;
  spec.method = "extended-linearization";
  spec.class_suffix = "ExtendedLinearization";
  spec.state_size = n;
  spec.params = runtime_params(m);
  spec.functions = model_functions(m);
  spec.functions.push_back(make_function(
      "injection", "Output injection k(y) with dk/dy(y_eps) = C(eps)^T (seed 001 eq. 34, 40).",
      {output_arg(y)}, k_y, "State"));
  GeneratedFunction x_rhs =
      make_function("x_rhs", "xh' = f(xh) + g(xh, u) + k(y) - k(h(xh))  (seed 001 eq. 29).",
                    {state_arg(m), input_arg(m), output_arg(y)}, rhs, "State");
  for (std::size_t l = 0; l < m.p(); ++l) x_rhs.lets.push_back({yh[l], m.h[l]});
  spec.functions.push_back(x_rhs);
  spec.state_name = "xh";
  spec.state_doc = "the estimate itself";
  spec.init = InitKind::identity;
  spec.update = UpdateKind::ode;
  spec.roles.rhs = "x_rhs";
  spec.estimate = EstimateKind::identity;
  return spec;
}

// The report rows: equations, constraints, family, poles, gain schedule and injection.
std::vector<ReportRow> el_report(const Model& m, const ExtendedLinearization& r) {
  std::vector<ReportRow> rows = {
      {"equations",
       "xh' = f(xh, u) + k(y) - k(h(xh)) (seed 001 eq. 29), dk/dy(y_eps) = C(eps)^T (eq. 34)"},
      {"parametrisation",
       m.p() == 1 ? std::string("eps = y - y0, the output level of the equilibrium (regular by "
                                "constraint (iii)); u is the model's first input")
                  : fmt::format("eps = y{0} - y0_{0}, the level of output {0} at the equilibrium "
                                "(regular by constraint (iii)); u is the model's first input",
                                r.level_output + 1)}};
  for (const auto& nt : r.notes) rows.push_back({"constraints", nt});
  rows.push_back({"equilibrium family", family_text(m, r)});
  rows.push_back(
      {"poles", fmt::format("{} ({})", poles_text(r.poles),
                            r.poles_given ? "given with --el-poles" : "default -1, -2, ..., -n")});
  if (m.p() == 1) {
    rows.push_back({"gain schedule C(eps)^T",
                    fmt::format("{} (Ackermann: p(A_eps) O_eps^-1 e_n{})", vec_text(r.c_eps),
                                r.family_closed ? "" : ", as a series")});
  } else {
    rows.push_back({"gain schedule C(eps)^T",
                    fmt::format("L0 + c(eps) w^T, w = {}, L0 = {}, c(eps) = {} (Ackermann on "
                                "(A_eps - L0 H_eps, w^T H_eps): p(A) O^-1 e_n{})",
                                combination_text(r.combination), pre_gain_text(r.pre_gain),
                                vec_text(r.c_eps), r.family_closed ? "" : ", as a series")});
  }
  rows.push_back(
      {"injection k(y)", fmt::format("{}; {}", vec_text(r.injection), injection_kind(r))});
  return rows;
}

ObserverSpec build_from(const Analysis& a, const ExtendedLinearization& r) {
  const Model& m = a.model;
  if (!r.failures.empty())
    throw UserError(SourceLoc{m.file, 0, 0},
                    fmt::format("method 'extended-linearization' does not apply: {}",
                                fmt::join(r.failures, "; ")));
  ObserverSpec spec = el_skeleton(m, r);
  spec.title = "Extended linearization observer (Baumann-Rugh; seed 001 §5)";
  spec.description = {
      "Observer: extended linearization (Baumann-Rugh 1986; seed 001 §5, eq. 27-45)",
      fmt::format("Eigenvalues of the linearized error along the equilibrium family: {}{}",
                  poles_text(r.poles), r.poles_given ? "" : " (default)"),
      fmt::format("Injection k(y): {}",
                  r.injection_closed
                      ? std::string("closed form (eq. 40)")
                      : fmt::format("series to order {} (eq. 42-45)", r.injection_order))};
  spec.class_doc = {
      "  xh' = f(xh) + g(xh, u) + k(y) - k(h(xh)),  dk/dy(y_eps) = C(eps)^T (Ackermann),",
      "so the error dynamics linearized at every equilibrium x_eps of the family have the",
      "prescribed eigenvalues (a local design: near the family)."};
  spec.constants.push_back({"poles", r.poles, "eigenvalues of the linearized error dynamics"});
  spec.report = el_report(m, r);
  spec.summary = fmt::format(
      "Extended linearization observer (Baumann-Rugh): linearized error eigenvalues {} along the "
      "equilibrium family ({}); injection {}",
      poles_text(r.poles), r.family_closed ? "closed form" : "series", injection_kind(r));
  return spec;
}

}  // namespace

ExtendedLinearization extended_linearization(const Model& m, const DesignOptions& o) {
  try {
    return run(m, o);
  } catch (const UserError&) {
    throw;
  } catch (const std::exception& e) {
    // A symbolic step failed (e.g. a series at a singular point): the design does not apply.
    ExtendedLinearization r;
    r.failures.push_back(std::string("the symbolic construction failed (the seed needs f, g and "
                                     "h analytic at the base point and along the family): ") +
                         e.what());
    return r;
  }
}

Design extended_linearization_design() {
  Design d;
  d.name = "extended-linearization";
  // Its verdict builds the design symbolically (family, Ackermann gain schedule, injection):
  // most of `check`'s time on small models, seconds on larger ones.
  d.verdict_searches = true;
  d.summary =
      "Extended linearization (Baumann-Rugh, seed 001 §5): nonlinear injection, linearized error "
      "eigenvalues invariant along the equilibrium family";
  d.options = {
      {"el-poles", "extended-linearization: eigenvalues of the linearized error, n negative reals",
       "-1, -2, ..., -n"},
      {"el-injection",
       "extended-linearization: injection k(y): auto (closed form when the integrals "
       "exist), closed, or series",
       "auto"},
      {"el-order", "extended-linearization: order m of the series injection (eq. 42-45)", "6"},
      {"el-family",
       "extended-linearization: equilibrium family: auto (closed form when found) or series",
       "auto"},
      {"el-family-order", "extended-linearization: order of the family's power series", "el-order"},
      {"el-base",
       "extended-linearization: base equilibrium, n + 1 numbers: the states, then the first input",
       "the origin, nominal input"}};
  d.plan = work_plan<ExtendedLinearization, extended_linearization, verdict_of, build_from>;
  return d;
}

}  // namespace obsynth
