#include "analysis/inverse.hpp"

#include <fmt/format.h>

#include <functional>

#include "symbolic/symbolic.hpp"
#include "symbolic/zero_test.hpp"

namespace obsynth {

using GiNaC::ex;

namespace {

// Known inverses of invertible atoms phi(xk): returns xk as a function of w = phi(xk).
std::optional<ex> invert_atom(const ex& atom, const GiNaC::symbol& xk, const ex& w) {
  if (!GiNaC::is_a<GiNaC::function>(atom)) return std::nullopt;
  const std::string n = GiNaC::ex_to<GiNaC::function>(atom).get_name();
  const ex arg = GiNaC::expand(atom.op(0));
  const ex a = arg.diff(xk);
  if (a.has(xk) || a.is_zero()) return std::nullopt;
  const ex b = GiNaC::expand(arg - a * xk);
  ex inner;
  if (n == "exp")
    inner = GiNaC::log(w);
  else if (n == "log")
    inner = GiNaC::exp(w);
  else if (n == "atan")
    inner = GiNaC::tan(w);
  else if (n == "tanh")
    inner = GiNaC::atanh(w);
  else
    return std::nullopt;
  return (inner - b) / a;
}

// The square root sqrt(a xk + b) (a free of xk, nonzero) as an invertible atom: w = sqrt(arg)
// gives xk = (w^2 - b) / a on the branch w >= 0.
bool is_affine_root(const ex& t, const GiNaC::symbol& xk) {
  if (!GiNaC::is_a<GiNaC::power>(t) || !t.op(1).is_equal(ex(1) / 2)) return false;
  const ex arg = GiNaC::expand(t.op(0));
  const ex a = arg.diff(xk);
  return !a.is_zero() && !a.has(xk);
}

}  // namespace

std::optional<ex> solve_for(const ex& eq, const GiNaC::symbol& xk, bool roots, ex* root_atom,
                            ex* root) {
  if (root_atom) *root_atom = 0;
  if (root) *root = 0;
  const ex e = GiNaC::expand(eq);
  const ex a = e.diff(xk);
  if (!a.is_zero() && !a.has(xk)) return GiNaC::normal(-e.subs(xk == 0) / a);
  // Linear in a single atom phi(xk)?
  std::vector<ex> atoms;
  std::function<void(const ex&)> find = [&](const ex& t) {
    if ((GiNaC::is_a<GiNaC::function>(t) || (roots && is_affine_root(t, xk))) && t.has(xk)) {
      for (const auto& q : atoms)
        if (q.is_equal(t)) return;
      atoms.push_back(t);
      return;
    }
    for (std::size_t i = 0; i < t.nops(); ++i) find(t.op(i));
  };
  find(e);
  if (atoms.size() != 1) return std::nullopt;
  GiNaC::symbol w("w_atom");
  const ex ew = e.subs(atoms[0] == w);
  if (ew.has(xk)) return std::nullopt;
  const ex aw = ew.diff(w);
  if (aw.is_zero() || aw.has(w)) return std::nullopt;
  const ex value = GiNaC::normal(-ew.subs(w == 0) / aw);
  if (GiNaC::is_a<GiNaC::power>(atoms[0])) {  // sqrt(a xk + b) = value
    const ex arg = GiNaC::expand(atoms[0].op(0));
    if (root_atom) *root_atom = atoms[0];
    if (root) *root = value;
    return GiNaC::normal((GiNaC::pow(value, 2) - arg.subs(xk == 0)) / arg.diff(xk));
  }
  return invert_atom(atoms[0], xk, value);
}

std::optional<std::vector<EliminationStep>> triangular_elimination(const ExVec& T, const Symbols& x,
                                                                   const Symbols& z, bool roots) {
  const std::size_t n = x.size();
  std::vector<bool> used(n, false), solved(n, false);
  std::vector<EliminationStep> steps;
  while (steps.size() < n) {
    std::optional<EliminationStep> pick;
    for (std::size_t i = 0; i < n && !pick; ++i) {
      if (used[i]) continue;
      std::vector<std::size_t> unknown;
      for (std::size_t k = 0; k < n; ++k)
        if (!solved[k] && T[i].has(x[k])) unknown.push_back(k);
      if (unknown.size() != 1) continue;
      ex root_atom, root;
      if (const auto v = solve_for(T[i] - z[i], x[unknown[0]], roots, &root_atom, &root))
        pick = EliminationStep{unknown[0], i, *v, root_atom, root};
    }
    if (!pick) return std::nullopt;
    used[pick->equation] = solved[pick->state] = true;
    steps.push_back(*pick);
  }
  return steps;
}

namespace {

// Elimination with substitution when no triangular order exists (e.g. a linear change of
// coordinates mixes the states): every value in z alone, simplified. Gives up (nullopt) once
// an expression exceeds `max_size` nodes, since expanding the composition can explode.
std::optional<std::vector<EliminationStep>> substituted_elimination(const ExVec& T,
                                                                    const Symbols& x,
                                                                    const Symbols& z,
                                                                    std::size_t max_size) {
  const std::size_t n = x.size();
  ExVec eqs;
  for (std::size_t i = 0; i < n; ++i) eqs.push_back(T[i] - z[i]);
  std::vector<bool> used(n, false), solved(n, false);
  std::vector<EliminationStep> steps;
  while (steps.size() < n) {
    std::optional<EliminationStep> pick;
    for (std::size_t i = 0; i < n && !pick; ++i)
      for (std::size_t k = 0; k < n && !used[i] && !pick; ++k)
        if (!solved[k] && eqs[i].has(x[k]))
          if (const auto v = solve_for(eqs[i], x[k])) pick = EliminationStep{k, i, *v};
    if (!pick) return std::nullopt;
    used[pick->equation] = solved[pick->state] = true;
    for (auto& s : steps) {
      s.value = simplify(s.value.subs(x[pick->state] == pick->value));
      if (expression_size(s.value) > max_size) return std::nullopt;
    }
    for (std::size_t q = 0; q < n; ++q) {
      if (used[q]) continue;
      eqs[q] = simplify(eqs[q].subs(x[pick->state] == pick->value));
      if (expression_size(eqs[q]) > max_size) return std::nullopt;
    }
    steps.push_back(*pick);
  }
  // Back-substitution left every value in z alone.
  for (const auto& s : steps)
    if (depends_on(s.value, x)) return std::nullopt;
  return steps;
}

ZeroVerdict worst(ZeroVerdict a, ZeroVerdict b) {
  return static_cast<int>(a) > static_cast<int>(b) ? a : b;
}

// Each step substituted into its own equation T_i(x) = z_i: zero when the step solves it.
// In triangular order the states of earlier steps stay symbols (the equation holds for any
// values of them, so together the steps satisfy every equation); values in z alone are
// substituted all at once.
ZeroVerdict verify_steps(const ExVec& T, const Symbols& x, const Symbols& z,
                         const std::vector<EliminationStep>& steps, bool triangular,
                         const SampleBoxes& boxes, const ZeroTestOptions& opt) {
  ZeroVerdict v = ZeroVerdict::proved;
  GiNaC::exmap all;
  for (const auto& s : steps) all[x[s.state]] = s.value;
  for (const auto& s : steps) {
    const ex own = (T[s.equation] - z[s.equation]).subs(x[s.state] == s.value);
    const ex residual = triangular ? own : own.subs(all);
    v = worst(v, zero_test(simplify(residual), boxes, opt));
    if (v == ZeroVerdict::nonzero) break;
  }
  return v;
}

// T^-1 in z: each step's value with the earlier states replaced by their compositions, by
// substitution only (GiNaC shares the subtrees; expanding would be exponential in depth).
ExVec compose(const Symbols& x, const std::vector<EliminationStep>& steps) {
  ExVec out(x.size());
  GiNaC::exmap earlier;
  for (const auto& s : steps) {
    out[s.state] = s.value.subs(earlier, GiNaC::subs_options::no_pattern);
    earlier[x[s.state]] = out[s.state];
  }
  return out;
}

}  // namespace

void build_inverse(const Model& m, Budget& budget, const CanonicalOptions& opt, CanonicalForm& cf) {
  const Symbols& x = m.states;
  auto steps = triangular_elimination(cf.T, x, cf.z);
  const bool triangular = steps.has_value();
  std::string how = "triangular elimination";
  if (!triangular) {
    steps = substituted_elimination(cf.T, x, cf.z, 2000);
    how = "elimination with substitution (no triangular order)";
  }
  budget.check();
  cf.T_inverse_kind = Availability::numeric;
  if (!steps) {
    cf.T_inverse_note =
        "no triangular elimination order, and elimination with substitution gave up (no "
        "solvable equation, or expressions beyond 2000 nodes); runtime Newton solve with [tau] "
        "as inverse Jacobian";
    return;
  }
  cf.T_inverse_verdict =
      verify_steps(cf.T, x, cf.z, *steps, triangular, m.sample_boxes(), opt.zero);
  if (cf.T_inverse_verdict == ZeroVerdict::nonzero) {
    cf.T_inverse_note =
        "elimination gave a branch that does not invert T; runtime Newton solve with [tau] as "
        "inverse Jacobian";
    return;
  }
  cf.T_inverse_steps = std::move(*steps);
  cf.T_inverse = compose(x, cf.T_inverse_steps);
  cf.T_inverse_kind = Availability::symbolic;
  cf.T_inverse_note =
      fmt::format("{} in {} steps, each {} in its own equation", how, cf.T_inverse_steps.size(),
                  cf.T_inverse_verdict == ZeroVerdict::proved ? "proved" : "verified numerically");
}

}  // namespace obsynth
