#include "analysis/triangular_form.hpp"

#include <fmt/format.h>

#include <algorithm>

#include "analysis/inverse.hpp"
#include "certify/enclosure.hpp"
#include "certify/tape.hpp"
#include "front/fresh_names.hpp"
#include "symbolic/expr_print.hpp"
#include "symbolic/symbolic.hpp"

namespace obsynth {

using GiNaC::ex;
using GiNaC::numeric;

const char* coordinates_name(TriangularForm::Coordinates c) {
  return c == TriangularForm::Coordinates::states ? "states" : "lie_derivatives";
}

std::size_t block_of(const std::vector<std::size_t>& blocks, std::size_t r) {
  std::size_t i = 0;
  for (std::size_t start = 0; i < blocks.size(); start += blocks[i++])
    if (r < start + blocks[i]) return i;
  return blocks.size();
}

std::size_t level_of(const std::vector<std::size_t>& blocks, std::size_t r) {
  for (const std::size_t k : blocks) {
    if (r < k) return r + 1;
    r -= k;
  }
  return 0;
}

std::vector<std::size_t> block_starts(const std::vector<std::size_t>& blocks) {
  std::vector<std::size_t> out;
  std::size_t start = 0;
  for (const std::size_t k : blocks) {
    out.push_back(start);
    start += k;
  }
  return out;
}

std::string z_label(const std::vector<std::size_t>& blocks, std::size_t r) {
  if (blocks.size() <= 1) return std::to_string(r + 1);
  return fmt::format("{},{}", block_of(blocks, r) + 1, level_of(blocks, r));
}

namespace {

// ---- zeros in a box ------------------------------------------------------------------------

numeric value_at(const ex& p, const GiNaC::symbol& s, const numeric& v) {
  return GiNaC::ex_to<numeric>(p.subs(GiNaC::exmap{{s, v}}));
}

int sign_of(const numeric& v) {
  return v.is_zero() ? 0 : (v.is_positive() ? 1 : -1);
}

// Distinct real roots of the rational polynomial p in (lo, hi] by Sturm's theorem.
int sturm_count(const ex& p, const GiNaC::symbol& s, const numeric& lo, const numeric& hi) {
  std::vector<ex> seq{p, p.diff(s)};
  while (!seq.back().is_zero() && seq.back().degree(s) > 0) {
    const ex r = GiNaC::expand(-GiNaC::rem(seq[seq.size() - 2], seq.back(), s));
    if (r.is_zero()) break;
    seq.push_back(r);
  }
  auto variations = [&](const numeric& at) {
    int count = 0, last = 0;
    for (const auto& q : seq) {
      const int sg = sign_of(value_at(q, s, at));
      if (sg == 0) continue;
      if (last != 0 && sg != last) ++count;
      last = sg;
    }
    return count;
  };
  return variations(lo) - variations(hi);
}

bool nonzero_by_balls(const ex& f, const SampleBoxes& boxes);

// Whether f is real on the whole box: every root or rational power has a base, and every log
// an argument, proved positive there (nonzero by balls and positive at the box's centre, as
// the box is connected). atanh is not handled. Ball arithmetic's natural-domain enclosures
// skip the points where f is not real, so this comes first.
bool real_on_box(const ex& f, const SampleBoxes& boxes) {
  const auto positive = [&](const ex& b) {
    if (!nonzero_by_balls(b, boxes)) return false;
    GiNaC::exmap centre;
    for (const auto& s : symbols_in(b)) {
      const Interval iv = boxes.box(s);
      centre[s] = (iv.lo + iv.hi) / 2;
    }
    GiNaC::numeric v;
    return evaluate_real(b, centre, 30, v) && v.is_positive();
  };
  if (GiNaC::is_a<GiNaC::power>(f) && !f.op(1).info(GiNaC::info_flags::integer) &&
      !positive(f.op(0)))
    return false;
  if (GiNaC::is_a<GiNaC::function>(f)) {
    const std::string n = GiNaC::ex_to<GiNaC::function>(f).get_name();
    if (n == "atanh" || (n == "log" && !positive(f.op(0)))) return false;
  }
  for (std::size_t k = 0; k < f.nops(); ++k)
    if (!real_on_box(f.op(k), boxes)) return false;
  return true;
}

// Proves f != 0 on the box when f is real there and Arb balls bound 1/f on all of it (branch
// and bound: every leaf box's enclosure of f excludes zero). A failure proves nothing.
bool nonzero_by_balls(const ex& f, const SampleBoxes& boxes) {
  if (GiNaC::is_a<numeric>(f)) return !f.is_zero();
  if (!real_on_box(f, boxes)) return false;
  certify::Box box;
  for (const auto& s : symbols_in(f)) {
    const Interval b = boxes.box(s);
    box.vars.push_back(s);
    box.ranges.push_back(
        {certify::detail::rational_lower(b.lo), certify::detail::rational_upper(b.hi)});
  }
  certify::EnclosureBudget budget;
  budget.max_boxes = 1024;
  budget.relative_gap = 1;  // any finite bound is a proof
  return certify::sup_abs(1 / f, box, budget).kind == certify::BoundKind::rigorous;
}

// One factor (not a product): never / somewhere / unknown, proved where it says so.
BoxZeros factor_zeros(const ex& f, const SampleBoxes& boxes) {
  if (GiNaC::is_a<numeric>(f))
    return f.is_zero() ? BoxZeros{BoxZeros::somewhere, "it is identically zero"}
                       : BoxZeros{BoxZeros::never, ""};
  if (GiNaC::is_a<GiNaC::function>(f) && GiNaC::ex_to<GiNaC::function>(f).get_name() == "exp")
    return {BoxZeros::never, ""};
  const auto vars = symbols_in(f);
  if (vars.size() == 1 && f.info(GiNaC::info_flags::rational_polynomial)) {
    const GiNaC::symbol& s = vars[0];
    const Interval b = boxes.box(s);
    const ex p = GiNaC::expand(f);
    const std::string name = s.get_name();
    for (const numeric& end : {b.lo, b.hi})
      if (value_at(p, s, end).is_zero())
        return {BoxZeros::somewhere,
                fmt::format("{} vanishes at {} = {}", to_string(f), name, to_string(end))};
    if (p.degree(s) == 1) {
      const numeric r =
          -GiNaC::ex_to<numeric>(p.coeff(s, 0)) / GiNaC::ex_to<numeric>(p.coeff(s, 1));
      if (r >= b.lo && r <= b.hi)
        return {BoxZeros::somewhere,
                fmt::format("{} vanishes at {} = {}", to_string(f), name, to_string(r))};
      return {BoxZeros::never, ""};
    }
    const int roots = sturm_count(p, s, b.lo, b.hi);
    if (roots == 0) return {BoxZeros::never, ""};
    return {BoxZeros::somewhere,
            fmt::format("{} has {} real root{} with {} in [{}, {}] (Sturm sequence)", to_string(f),
                        roots, roots == 1 ? "" : "s", name, to_string(b.lo), to_string(b.hi))};
  }
  if (nonzero_by_balls(f, boxes)) return {BoxZeros::never, ""};
  // Sampled: an exact zero or a sign change proves a zero; nothing proves there is none.
  const ZeroTestOptions zopt;
  const auto points = sample_points(vars, boxes, 32, zopt.seed);
  int last_sign = 0;
  const GiNaC::exmap* last_pt = nullptr;
  auto point_text = [&](const GiNaC::exmap& pt) {
    std::vector<std::string> parts;
    for (const auto& s : vars)
      parts.push_back(fmt::format("{} = {}", s.get_name(),
                                  to_string(GiNaC::evalf(pt.at(s)))));  // approximate
    return fmt::format("{}", fmt::join(parts, ", "));
  };
  for (const auto& pt : points) {
    numeric v, mag;
    if (!evaluate_with_magnitude(f, pt, zopt.digits, v, mag)) continue;
    const ex exact = f.subs(pt);
    if (GiNaC::is_a<numeric>(exact) && exact.is_zero())
      return {BoxZeros::somewhere, fmt::format("{} vanishes at {}", to_string(f), point_text(pt))};
    if (GiNaC::abs(v) <= numeric(10).power(-(zopt.digits - 10)) * mag) continue;  // unclear
    const int sg = sign_of(v);
    if (last_sign != 0 && sg != last_sign)
      return {BoxZeros::somewhere, fmt::format("{} changes sign between ({}) and ({})",
                                               to_string(f), point_text(*last_pt), point_text(pt))};
    last_sign = sg;
    last_pt = &pt;
  }
  return {BoxZeros::unknown,
          fmt::format("{}: no zero found at {} sampled points (sampled, not proved)", to_string(f),
                      points.size())};
}

void collect_factors(const ex& e, std::vector<ex>& out) {
  if (GiNaC::is_a<GiNaC::mul>(e)) {
    for (std::size_t k = 0; k < e.nops(); ++k) collect_factors(e.op(k), out);
  } else if (GiNaC::is_a<GiNaC::power>(e) && GiNaC::is_a<numeric>(e.op(1))) {
    collect_factors(e.op(0), out);  // b^k vanishes (k > 0) or is undefined (k < 0) where b = 0
  } else {
    out.push_back(e);
  }
}

}  // namespace

BoxZeros zeros_in_box(const ex& e, const SampleBoxes& boxes) {
  ex whole = e;
  if (!has_transcendental(e)) {
    const ex nd = GiNaC::normal(e);
    whole = GiNaC::factor(GiNaC::numer(nd)) * GiNaC::factor(GiNaC::denom(nd));
  }
  std::vector<ex> factors;
  collect_factors(whole, factors);
  BoxZeros out{BoxZeros::never, ""};
  std::vector<std::string> unknown;
  for (const auto& f : factors) {
    const BoxZeros z = factor_zeros(f, boxes);
    if (z.kind == BoxZeros::somewhere) return z;
    if (z.kind == BoxZeros::unknown) unknown.push_back(z.detail);
  }
  if (!unknown.empty()) out = {BoxZeros::unknown, fmt::format("{}", fmt::join(unknown, "; "))};
  return out;
}

namespace {

// ---- the form ------------------------------------------------------------------------------

void finish(TriangularForm& t, std::size_t n) {
  t.A.assign(n, ExVec(n, ex(0)));
  for (std::size_t i = 0; i + 1 < n; ++i) t.A[i][i + 1] = t.a[i];
  t.C.assign(n, ex(0));
  t.C[0] = 1;
}

// z a permutation of x: y = x_j and each x' affine in exactly one new state.
// The state the output is (the first z of the form in the states), or nullopt with `why`.
std::optional<std::size_t> output_state(const Model& m, std::string& why) {
  const ex h = simplify(m.h[0]);
  for (std::size_t j = 0; j < m.n(); ++j)
    if (GiNaC::is_a<GiNaC::symbol>(h) && GiNaC::ex_to<GiNaC::symbol>(h) == m.states[j]) return j;
  why = fmt::format("the output {} is not a state", to_string(h));
  return std::nullopt;
}

std::optional<TriangularForm> in_states(const Model& m, const ExVec& F, std::size_t first,
                                        std::string& why) {
  const std::size_t n = m.n();
  const Symbols& x = m.states;
  TriangularForm t;
  t.coordinates = TriangularForm::Coordinates::states;
  t.order = {first};
  std::vector<bool> used(n, false);
  used[first] = true;
  for (std::size_t i = 0; i + 1 < n; ++i) {
    const std::size_t s = t.order[i];
    const ex Fi = F[s];
    std::vector<std::size_t> fresh;
    for (std::size_t k = 0; k < n; ++k)
      if (!used[k] && Fi.has(x[k])) fresh.push_back(k);
    const std::string lhs = x[s].get_name() + "'";
    if (fresh.empty()) {
      why = fmt::format(
          "{} = {} involves none of the states not yet reached (a_{} = 0 for every "
          "input)",
          lhs, to_string(Fi), i + 1);
      return std::nullopt;
    }
    if (fresh.size() > 1) {
      std::vector<std::string> names;
      for (auto k : fresh) names.push_back(x[k].get_name());
      why = fmt::format("{} involves several states not yet reached ({})", lhs,
                        fmt::join(names, ", "));
      return std::nullopt;
    }
    const std::size_t k = fresh[0];
    const ex c = simplify(Fi.diff(x[k]));
    if (depends_on(c, x)) {
      why = fmt::format("{} is not affine in {} with a state-free coefficient (d/d{} = {})", lhs,
                        x[k].get_name(), x[k].get_name(), to_string(c));
      return std::nullopt;
    }
    const ex rest = simplify(Fi - c * x[k]);
    if (rest.has(x[k])) {
      why = fmt::format("{} is not affine in {}", lhs, x[k].get_name());
      return std::nullopt;
    }
    t.a.push_back(c);
    t.phi_x.push_back(rest);
    t.order.push_back(k);
    used[k] = true;
  }
  t.phi_x.push_back(F[t.order.back()]);
  t.z = fresh_symbols(m, "z", n);
  GiNaC::exmap to_z;
  t.x_of_z.assign(n, ex(0));
  for (std::size_t i = 0; i < n; ++i) {
    t.z_of_x.push_back(x[t.order[i]]);
    t.x_of_z[t.order[i]] = t.z[i];
    to_z[x[t.order[i]]] = t.z[i];
  }
  for (const auto& p : t.phi_x) t.phi.push_back(p.subs(to_z));
  finish(t, n);
  return t;
}

// The states in z from an elimination sequence. A state solved through a square root,
// sqrt(a x + b) = w, is (P^2 - b) / a with P a positive symbol while substituting, so that the
// roots of it fold back to P (GiNaC simplifies sqrt(P^2) to P for positive P); in_z then puts
// the root's value w for P. This keeps the branch w >= 0 (the image of the states) instead of
// leaving |w| = sqrt(w^2) in phi.
struct SolvedStates {
  GiNaC::exmap states;  // state -> value in z and the P
  GiNaC::exmap roots;   // P -> w, in z and earlier P
  ex in_z(ex e) const {
    for (std::size_t k = 0; k <= roots.size() && !roots.empty(); ++k) e = e.subs(roots);
    return e;
  }
};

SolvedStates substitution_of(const Symbols& x, const std::vector<EliminationStep>& steps) {
  SolvedStates s;
  for (const auto& st : steps) {
    const GiNaC::symbol& xs = x[st.state];
    if (st.root.is_zero()) {
      s.states[xs] = st.value.subs(s.states);
      continue;
    }
    const GiNaC::possymbol P("root_" + xs.get_name());
    const ex arg = GiNaC::expand(st.root_atom.op(0));
    const ex a = arg.diff(xs);
    s.states[xs] = ((P * P - GiNaC::expand(arg - a * xs)) / a).subs(s.states);
    s.roots[P] = st.root.subs(s.states);
  }
  return s;
}

// z = (h, L_f h, ..., L_f^{n-1} h): a_i = 1, phi_i = L_g z_i (i < n), phi_n = L_{f+g} z_n.
std::optional<TriangularForm> in_lie_coordinates(const Model& m, const ExVec& F,
                                                 const ExVec* drift_lie, std::string& why) {
  const std::size_t n = m.n();
  const Symbols& x = m.states;
  TriangularForm t;
  t.coordinates = TriangularForm::Coordinates::lie_derivatives;
  if (drift_lie && drift_lie->size() == n) {
    t.z_of_x = *drift_lie;
  } else {
    t.z_of_x.push_back(simplify(m.h[0]));
    for (std::size_t k = 1; k < n; ++k)
      t.z_of_x.push_back(simplify(lie_derivative(t.z_of_x.back(), m.f, x)));
  }
  t.z = fresh_symbols(m, "z", n);
  const auto steps = triangular_elimination(t.z_of_x, x, t.z, true);
  if (!steps) {
    why =
        "no explicit inverse of z = (h, L_f h, ...) by elimination (it may not be a "
        "coordinate system)";
    return std::nullopt;
  }
  const SolvedStates solved = substitution_of(x, *steps);
  t.x_of_z.assign(n, ex(0));
  for (std::size_t j = 0; j < n; ++j) {
    const auto it = solved.states.find(x[j]);
    if (it == solved.states.end()) {
      why = fmt::format("the elimination does not give {}", x[j].get_name());
      return std::nullopt;
    }
    t.x_of_z[j] = solved.in_z(it->second);
  }
  for (std::size_t i = 0; i < n; ++i) {
    const ex phix = simplify(lie_derivative(t.z_of_x[i], i + 1 < n ? m.g : F, x));
    const ex phiz = simplify(solved.in_z(phix.subs(solved.states)));
    for (std::size_t j = i + 1; j < n; ++j)
      if (phiz.has(t.z[j])) {
        why = fmt::format("phi_{} = {} depends on z{} (not triangular)", i + 1, to_string(phiz),
                          j + 1);
        return std::nullopt;
      }
    if (depends_on(phiz, x)) {
      why = fmt::format("phi_{} still depends on x after substituting the inverse", i + 1);
      return std::nullopt;
    }
    t.phi_x.push_back(phix);
    t.phi.push_back(phiz);
  }
  t.a.assign(n > 0 ? n - 1 : 0, ex(1));
  finish(t, n);
  return t;
}

}  // namespace

std::optional<TriangularForm> triangular_form(const Model& m, std::string* why,
                                              const ExVec* drift_lie, bool lie_coordinates) {
  std::string local;
  std::string& w = why ? *why : local;
  if (m.p() != 1) {
    w = fmt::format("the form has one output; the model has {}", m.p());
    return std::nullopt;
  }
  if (depends_on(m.h[0], m.inputs)) {
    w = "the output depends on the input (the form needs y = z_1 = h(x))";
    return std::nullopt;
  }
  // The field in canonical form only when a way needs it: expanding a large field is the
  // costly part, and the output decides the first way at once.
  ExVec F;
  const auto field = [&]() -> const ExVec& {
    if (F.empty())
      for (const auto& e : m.field()) F.push_back(simplify(e));
    return F;
  };
  std::string why_states, why_lie;
  if (const auto first = output_state(m, why_states))
    if (auto t = in_states(m, field(), *first, why_states)) return t;
  if (!lie_coordinates)
    why_lie = "not tried: the symbolic Lie derivatives were skipped";
  else if (auto t = in_lie_coordinates(m, field(), drift_lie, why_lie))
    return t;
  w = fmt::format("not in the form in the states ({}), nor in the coordinates (h, L_f h, ...) ({})",
                  why_states, why_lie);
  return std::nullopt;
}

std::optional<TriangularForm> block_triangular_form(const Model& m,
                                                    const std::vector<std::size_t>& indices,
                                                    std::string* why) {
  std::string local;
  std::string& w = why ? *why : local;
  const std::size_t n = m.n(), p = m.p();
  std::size_t sum = 0;
  for (const std::size_t k : indices) sum += k;
  if (indices.size() != p || sum != n ||
      std::find(indices.begin(), indices.end(), std::size_t{0}) != indices.end()) {
    w = fmt::format(
        "the observability indices ({}) do not give {} blocks of sizes >= 1 summing to n = {}",
        fmt::join(indices, ", "), p, n);
    return std::nullopt;
  }
  for (const auto& h : m.h)
    if (depends_on(h, m.inputs)) {
      w = "an output depends on the input (the form needs y_i = z_{i,1} = h_i(x))";
      return std::nullopt;
    }
  TriangularForm t;
  t.coordinates = TriangularForm::Coordinates::lie_derivatives;
  t.blocks = indices;
  for (std::size_t i = 0; i < p; ++i) {
    ex e = simplify(m.h[i]);
    for (std::size_t j = 0; j < indices[i]; ++j) {
      t.z_of_x.push_back(e);
      e = simplify(lie_derivative(e, m.f, m.states));
    }
  }
  t.z = fresh_symbols(m, "z", n);
  const auto steps = triangular_elimination(t.z_of_x, m.states, t.z, true);
  if (!steps) {
    w = "no explicit inverse of the block coordinates z_{i,j} = L_f^{j-1} h_i by elimination";
    return std::nullopt;
  }
  const SolvedStates solved = substitution_of(m.states, *steps);
  t.x_of_z.assign(n, ex(0));
  for (std::size_t j = 0; j < n; ++j) {
    const auto it = solved.states.find(m.states[j]);
    if (it == solved.states.end()) {
      w = fmt::format("the elimination does not give {}", m.states[j].get_name());
      return std::nullopt;
    }
    t.x_of_z[j] = solved.in_z(it->second);
  }
  ExVec F;
  for (const auto& e : m.field()) F.push_back(simplify(e));
  for (std::size_t r = 0; r < n; ++r) {
    const bool last = level_of(indices, r) == indices[block_of(indices, r)];
    const ex phix = simplify(lie_derivative(t.z_of_x[r], last ? F : m.g, m.states));
    const ex phiz = simplify(solved.in_z(phix.subs(solved.states)));
    for (std::size_t c = 0; c < n; ++c)
      if (level_of(indices, c) > level_of(indices, r) && phiz.has(t.z[c])) {
        w = fmt::format(
            "phi_{} = {} depends on z_{} (z{}), of a higher level (not block triangular: "
            "phi_{{i,j}} "
            "may depend on z_{{l,1..j}} only)",
            z_label(indices, r), to_string(phiz), z_label(indices, c), c + 1);
        return std::nullopt;
      }
    if (depends_on(phiz, m.states)) {
      w = fmt::format("phi_{} still depends on x after substituting the inverse",
                      z_label(indices, r));
      return std::nullopt;
    }
    t.phi_x.push_back(phix);
    t.phi.push_back(phiz);
  }
  const auto starts = block_starts(indices);
  for (std::size_t r = 0; r + 1 < n; ++r)
    t.a.push_back(std::find(starts.begin(), starts.end(), r + 1) != starts.end() ? ex(0) : ex(1));
  finish(t, n);
  return t;
}

}  // namespace obsynth
