#include "analysis/observability.hpp"
#include "analysis/observability_ring.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <limits>
#include <new>
#include <optional>
#include <set>

#include "analysis/flint_mpoly.hpp"
#include "symbolic/expr_print.hpp"
#include "symbolic/poly.hpp"
#include "symbolic/symbolic.hpp"
#include "symbolic/zero_test.hpp"

namespace obsynth {

using GiNaC::ex;
using GiNaC::numeric;

std::size_t numeric_rank(std::vector<std::vector<numeric>> a, bool exact) {
  const std::size_t rows = a.size();
  if (rows == 0) return 0;
  const std::size_t cols = a[0].size();
  const numeric eps = exact ? numeric(0) : numeric(10).power(numeric(-30));
  if (!exact) {
    // Scale rows to unit max-norm: the rows of O span many decades (design.md §5).
    for (auto& r : a) {
      numeric mx = 0;
      for (const auto& v : r) mx = std::max(mx, GiNaC::abs(v));
      if (!mx.is_zero())
        for (auto& v : r) v = v / mx;
    }
  }
  std::size_t rank = 0;
  for (std::size_t c = 0; c < cols && rank < rows; ++c) {
    std::size_t piv = rank;
    numeric best = GiNaC::abs(a[rank][c]);
    for (std::size_t r = rank + 1; r < rows; ++r)
      if (GiNaC::abs(a[r][c]) > best) {
        best = GiNaC::abs(a[r][c]);
        piv = r;
      }
    if (best <= eps || best.is_zero()) continue;
    std::swap(a[piv], a[rank]);
    for (std::size_t r = rank + 1; r < rows; ++r) {
      if (a[r][c].is_zero()) continue;
      const numeric factor = a[r][c] / a[rank][c];
      for (std::size_t k = c; k < cols; ++k) a[r][k] -= factor * a[rank][k];
    }
    ++rank;
  }
  return rank;
}

namespace {

// The x-dependent ones of the factors `fac` (a product or one factor; atoms frozen as the
// symbols of `back`), without multiplicity, integer content or sign; exp(.) factors dropped.
ExVec normalised_factors(const ex& fac, const GiNaC::exmap& back, const Symbols& x) {
  std::vector<ex> parts;
  auto add = [&](const ex& f) {
    ex g = f;
    if (GiNaC::is_a<GiNaC::power>(g) && GiNaC::is_a<numeric>(g.op(1))) g = g.op(0);
    if (!depends_on(g.subs(back), x)) return;
    // Drop the integer content: 2*x1^2 + 2*x2^2 vanishes where x1^2 + x2^2 does.
    if (g.info(GiNaC::info_flags::polynomial)) {
      const GiNaC::ex ge = GiNaC::expand(g);
      const GiNaC::numeric ic = ge.integer_content();
      if (!ic.is_zero()) g = ge / ic;
    }
    g = g.subs(back);
    // exp(.) never vanishes on the reals: it cannot be where the rank drops.
    if (GiNaC::is_a<GiNaC::function>(g) && GiNaC::ex_to<GiNaC::function>(g).get_name() == "exp")
      return;
    parts.push_back(g);
  };
  if (GiNaC::is_a<GiNaC::mul>(fac)) {
    for (std::size_t i = 0; i < fac.nops(); ++i) add(fac.op(i));
  } else {
    add(fac);
  }
  // Normalise sign (leading printed term positive) and deduplicate.
  std::map<std::string, ex> unique;
  for (auto& f : parts) {
    std::string s = to_string(f);
    if (!s.empty() && s[0] == '-') {
      f = GiNaC::expand(-f);
      s = to_string(f);
    }
    unique.emplace(s, f);
  }
  ExVec out;
  for (auto& [s, f] : unique) out.push_back(f);
  return out;
}

}  // namespace

ExVec dependent_factors(const ex& e, const Symbols& x) {
  GiNaC::exmap repl;
  const ex num = GiNaC::numer(GiNaC::normal(e));
  const ex poly = num.to_polynomial(repl);
  GiNaC::exmap back;
  for (const auto& [k, v] : repl) back[k] = v;
  return normalised_factors(GiNaC::factor(poly), back, x);
}

namespace {

ExVec denominators(const ExMatrix& O, const Symbols& x) {
  std::map<std::string, ex> unique;
  for (const auto& row : O)
    for (const auto& e : row) {
      if (!has_denominator_in(e, x)) continue;  // cheap structural test first
      for (const auto& f : dependent_factors(GiNaC::denom(e), x)) unique.emplace(to_string(f), f);
    }
  ExVec out;
  for (auto& [s, f] : unique) out.push_back(f);
  return out;
}

// Rank-drop set and the poles of det O; `factored`: det O is a ring polynomial (no poles)
// whose factors FLINT already found.
void finish_determinant(Observability& ob, const Symbols& x, bool factored = false) {
  if (factored) return;
  ob.rank_drop = dependent_factors(ob.det, x);
  for (const auto& f : dependent_factors(GiNaC::denom(GiNaC::normal(ob.det)), x)) {
    const std::string s = to_string(f);
    bool seen = false;
    for (const auto& u : ob.undefined) seen |= to_string(u) == s;
    if (!seen) ob.undefined.push_back(f);
  }
}

struct PointMatrix {
  std::vector<std::vector<numeric>> a;
  bool valid = true;
};

PointMatrix evaluate_matrix(const ExMatrix& O, const GiNaC::exmap& pt, bool exact, int digits) {
  PointMatrix pm;
  const numeric rounding = numeric(10).power(-(digits - 10));
  for (const auto& row : O) {
    std::vector<numeric> r;
    for (const auto& e : row) {
      numeric v;
      if (exact) {
        try {
          const ex val = e.subs(pt);
          if (!GiNaC::is_a<numeric>(val)) {
            pm.valid = false;
            return pm;
          }
          v = GiNaC::ex_to<numeric>(val);
        } catch (const std::exception&) {
          pm.valid = false;
          return pm;
        }
      } else {
        numeric mag;
        if (!evaluate_with_magnitude(e, pt, digits, v, mag)) {
          pm.valid = false;
          return pm;
        }
        // Zero within rounding: the row scaling below would otherwise blow noise up to 1.
        if (GiNaC::abs(v) <= rounding * mag) v = 0;
      }
      r.push_back(v);
    }
    pm.a.push_back(std::move(r));
  }
  return pm;
}

}  // namespace

// Columns c_0, c_1, ... such that row k of a is zero beyond {c_0..c_k} and nonzero at c_k
// (structurally, on simplified entries), if they exist. Greedy is exact: row k's nonzero
// columns outside {c_0..c_{k-1}} must be the single column c_k.
std::optional<std::vector<std::size_t>> triangular_columns(const ExMatrix& a) {
  const std::size_t n = a.size();
  std::vector<std::size_t> cols;
  std::vector<bool> taken(n, false);
  for (std::size_t k = 0; k < n; ++k) {
    std::optional<std::size_t> fresh;
    for (std::size_t c = 0; c < n; ++c) {
      if (taken[c] || a[k][c].is_zero()) continue;
      if (fresh) return std::nullopt;
      fresh = c;
    }
    if (!fresh) return std::nullopt;
    taken[*fresh] = true;
    cols.push_back(*fresh);
  }
  return cols;
}

namespace {

// The Lie chain's gradients as ring polynomials, kept for the fraction-free determinant.
struct RingRows {
  std::optional<PolyRing> ring;
  std::unique_ptr<MPolyContext> ctx;
  std::vector<std::vector<std::vector<Poly>>> grads;  // [output][order][state]
};

// lie_chain_with_gradients in the polynomial ring, when f and h live in it: the same
// (expanded) results, the products in FLINT (flint_mpoly.hpp) when no Laurent exponent occurs.
// expressions false: only the ring rows (lie and grads stay empty).
bool lie_chain_in_ring(const Model& m, Budget& budget, std::vector<ExVec>& lie,
                       std::vector<ExMatrix>& grads, RingRows& rows, bool expressions = true) {
  ExVec all(m.f);
  all.insert(all.end(), m.h.begin(), m.h.end());
  rows.ring = PolyRing::for_expressions(all, m.states);
  if (!rows.ring) return false;
  const PolyRing& ring = *rows.ring;
  try {
    std::vector<Poly> field;
    for (const auto& e : m.f) field.push_back(*ring.from_ex(e));
    std::vector<Poly> outputs;
    for (const auto& e : m.h) outputs.push_back(*ring.from_ex(e));
    std::vector<const Poly*> seen;
    for (const auto& p : field) seen.push_back(&p);
    for (const auto& p : outputs) seen.push_back(&p);
    rows.ctx = MPolyContext::for_polys(ring, seen);
    std::vector<MPoly> flint_field;  // converted at the first product worth FLINT
    auto lie_derivative = [&](const Poly& phi, const std::vector<Poly>& grad) {
      if (!rows.ctx || product_work(grad, field) < kFlintProductWork)
        return PolyRing::dot(grad, field);
      if (flint_field.empty())
        for (const auto& p : field) flint_field.push_back(rows.ctx->to_flint(p));
      return lie_derivative_flint(ring, *rows.ctx, phi, flint_field);
    };
    const std::size_t n = m.n();
    rows.grads.assign(m.p(), {});
    for (std::size_t i = 0; i < m.p(); ++i) {
      Poly phi = outputs[i];
      ExVec chain;
      if (expressions) chain.push_back(ring.to_ex(phi));
      for (std::size_t k = 0; k < n; ++k) {
        std::vector<Poly> grad;
        ExVec row;
        for (std::size_t j = 0; j < n; ++j) {
          grad.push_back(ring.derivative(phi, j));
          if (expressions) row.push_back(ring.to_ex(grad.back()));
        }
        if (expressions) grads[i].push_back(std::move(row));
        if (k + 1 < n) {
          phi = lie_derivative(phi, grad);
          budget.check(phi.node_estimate());
          if (expressions) chain.push_back(ring.to_ex(phi));
        }
        rows.grads[i].push_back(std::move(grad));
      }
      if (expressions) lie.push_back(std::move(chain));
    }
  } catch (const PolyOverflow&) {
    rows = RingRows{};
    return false;
  }
  return true;
}

// det and adj(O) e_n of the selected rows by fraction-free elimination in FLINT, when the
// rows are ring polynomials, with r = adj(O) e_n / det O in lowest terms and the factors of det
// O (`factored` when FLINT factored it); false otherwise (the caller expands cofactors with
// GiNaC).
bool determinant_in_ring(Observability& ob, const RingRows& rows, const Symbols& x,
                         bool& factored) {
  if (!rows.ctx) return false;
  try {
    std::vector<std::vector<MPoly>> a;
    for (std::size_t r : ob.selected) {
      const RowId id = ob.rows[r];
      std::vector<MPoly> row;
      for (const auto& p : rows.grads[id.output][id.order]) row.push_back(rows.ctx->to_flint(p));
      a.push_back(std::move(row));
    }
    auto dc = det_and_last_row_cofactors(*rows.ctx, std::move(a));
    if (!dc) return false;  // formally singular: leave it to the generic path
    const PolyRing& ring = *rows.ring;
    const MPolyContext& ctx = *rows.ctx;
    ob.det = ring.to_ex(ctx.from_flint(dc->det));
    ob.last_row_cofactors.clear();
    ob.r.clear();
    for (const auto& c : dc->cofactors) {
      ob.last_row_cofactors.push_back(ring.to_ex(ctx.from_flint(c)));
      const Quotient q = reduced_quotient(ctx, c, dc->det);
      ob.r.push_back(ring.to_ex(ctx.from_flint(q.num)) / ring.to_ex(ctx.from_flint(q.den)));
    }
    if (const auto fs = irreducible_factors(ctx, dc->det)) {
      GiNaC::exvector parts;
      for (const auto& f : *fs) parts.push_back(ring.to_ex(ctx.from_flint(f)));
      ob.rank_drop = normalised_factors(GiNaC::mul(parts), {}, x);
      factored = true;
    }
  } catch (const PolyOverflow&) {
    return false;
  }
  return true;
}

// Generically nonzero: exactly for rational entries (simplified forms are canonical), by the
// zero test otherwise.
bool generically_nonzero(const ex& e, const SampleBoxes& boxes, bool& exact) {
  if (!has_transcendental(e)) return !simplify(e).is_zero();
  exact = false;
  return zero_test(e, boxes) == ZeroVerdict::nonzero;
}

int permutation_sign(const std::vector<std::size_t>& perm) {
  int sign = 1;
  std::vector<bool> seen(perm.size(), false);
  for (std::size_t i = 0; i < perm.size(); ++i) {
    if (seen[i]) continue;
    std::size_t len = 0;
    for (std::size_t j = i; !seen[j]; j = perm[j], ++len) seen[j] = true;
    if (len % 2 == 0) sign = -sign;
  }
  return sign;
}

}  // namespace

namespace {

// The rank from Taylor jets; the symbolic results stay empty (`why` says why).
Observability observability_from_jets(const Model& m, Budget& budget,
                                      const ObservabilityOptions& opt, const std::string& why) {
  Observability ob;
  ob.n = m.n();
  ob.p = m.p();
  StageScope stage(budget, "jets");
  JetsRank jr = jets_rank(m, opt.jets, &budget);
  for (std::size_t k = 0; k < ob.n; ++k)
    for (std::size_t i = 0; i < ob.p; ++i) ob.rows.push_back({i, k});
  ob.generic_rank = jr.rank;
  ob.rank_exact = jr.arithmetic == JetsArithmetic::modular;
  ob.indices = jr.indices;
  ob.selected = jr.selected;
  ob.jets = std::move(jr);
  ob.symbolic_skipped = why;
  return ob;
}

// GiNaC's Lie chain, for every output.
void ginac_lie_chain(const Model& m, const Budget* budget, std::vector<ExVec>& lie,
                     std::vector<ExMatrix>& grads) {
  lie.clear();
  for (std::size_t i = 0; i < m.p(); ++i) {
    LieChain chain = lie_chain_with_gradients(m.h[i], m.f, m.states, m.n(), budget);
    lie.push_back(std::move(chain.derivatives));
    grads[i] = std::move(chain.gradients);
  }
}

// The Lie chain and its gradients (rows of O per output), in the ring when possible. Its own
// budget stops it on size (deterministic); in automatic mode it has no clock of its own, so that
// no wall-clock limit chooses between it and the jets (the work budget does, see
// symbolic_or_fallback).
void lie_chain(const Model& m, Budget& budget, const ObservabilityOptions& opt, Observability& ob,
               std::vector<ExMatrix>& grads, RingRows& ring_rows, bool expressions) {
  StageScope stage(budget, "lie");
  BudgetLimits limits = budget.limits();
  if (opt.rank_method == RankMethod::automatic)
    limits.stage_seconds = std::numeric_limits<double>::infinity();
  Budget own(limits);
  own.begin("lie");
  if (lie_chain_in_ring(m, own, ob.lie, grads, ring_rows, expressions)) return;
  ginac_lie_chain(m, &own, ob.lie, grads);
}

// The rank, det and adj(O) e_n of a triangular O from its diagonal entries (O[k][cols[k]]):
// false when some entry is generically zero.
bool triangular_rank_from_diagonal(Observability& ob, const std::vector<std::size_t>& cols,
                                   const ExVec& diagonal, const SampleBoxes& boxes,
                                   const Symbols& x) {
  bool exact = true, regular = true;
  for (std::size_t k = 0; k < ob.n && regular; ++k)
    regular = generically_nonzero(diagonal[k], boxes, exact);
  if (!regular) return false;
  ob.triangular = true;
  ob.diag_columns = cols;
  ob.rank_exact = exact;
  ob.generic_rank = ob.n;
  ob.indices = {ob.n};
  for (std::size_t k = 0; k < ob.n; ++k) ob.selected.push_back(k);
  // det = sign(perm) prod_k O[k][c_k]; adj(O) e_n = det O^-1 e_n = det e_{c_n} / O[n][c_n].
  ex det = permutation_sign(cols), head = det;
  for (std::size_t k = 0; k < ob.n; ++k) {
    det *= diagonal[k];
    if (k + 1 < ob.n) head *= diagonal[k];
  }
  ob.det = combine_exponentials(det);  // exp(a)*exp(b) as exp(a+b), still factored
  ob.last_row_cofactors.assign(ob.n, 0);
  ob.last_row_cofactors[cols.back()] = head;
  finish_determinant(ob, x);
  return true;
}

// One output whose O is triangular up to a column permutation with a generically nonzero
// diagonal: rank n, and det (and adj(O) e_n) as products, without sampling. False otherwise.
bool triangular_rank(Observability& ob, const SampleBoxes& boxes, const Symbols& x) {
  if (ob.p != 1) return false;
  const auto cols = triangular_columns(ob.O);
  if (!cols) return false;
  ExVec diagonal;
  for (std::size_t k = 0; k < ob.n; ++k) diagonal.push_back(ob.O[k][(*cols)[k]]);
  return triangular_rank_from_diagonal(ob, *cols, diagonal, boxes, x);
}

// The generic rank of O from its values at sample points of the states and free parameters
// (O does not depend on u) into ob; returns O at the point of the largest rank.
std::vector<std::vector<numeric>> sampled_rank(const Model& m, const SampleBoxes& boxes,
                                               const ObservabilityOptions& opt, bool exact,
                                               Budget& budget, Observability& ob) {
  std::vector<GiNaC::symbol> syms(m.states);
  for (const auto& s : m.free_params()) syms.push_back(s);
  // Several points; some may be invalid (poles, log of negatives): take up to 4x as many.
  const auto points = sample_points(syms, boxes, opt.rank_points * 4, opt.seed);
  int used = 0;
  std::vector<std::vector<numeric>> best_matrix;
  for (const auto& pt : points) {
    if (used >= opt.rank_points) break;
    PointMatrix pm = evaluate_matrix(ob.O, pt, exact, opt.float_digits);
    if (!pm.valid) continue;
    ++used;
    const std::size_t r = numeric_rank(pm.a, exact);
    if (r > ob.generic_rank || best_matrix.empty()) {
      ob.generic_rank = std::max(ob.generic_rank, r);
      best_matrix = pm.a;
    }
    budget.check();
    if (ob.generic_rank == ob.n) break;  // full column rank: no point can show more
  }
  if (used == 0)
    throw UserError(SourceLoc{m.file, 0, 0},
                    "the observability matrix is undefined at every sampled point of the domain; "
                    "declare a 'domain' where the model is defined");
  return best_matrix;
}

// Observability indices: add rows in k-major order, keeping those that raise the rank (of O
// at the sample point a).
void observability_indices(const std::vector<std::vector<numeric>>& a, bool exact,
                           Observability& ob) {
  ob.indices.assign(ob.p, 0);
  std::vector<bool> stopped(ob.p, false);
  std::vector<std::vector<numeric>> acc;
  for (std::size_t r = 0; r < ob.O.size(); ++r) {
    const std::size_t i = ob.rows[r].output;
    if (stopped[i]) continue;
    acc.push_back(a[r]);
    if (numeric_rank(acc, exact) == acc.size()) {
      ob.selected.push_back(r);
      ++ob.indices[i];
    } else {
      acc.pop_back();
      stopped[i] = true;
    }
  }
}

// det of the selected rows by cofactor expansion along the last one; the cofactors are
// adj(O) e_n.
void cofactor_determinant(const Symbols& x, Budget& budget, Observability& ob) {
  const std::size_t n = ob.n;
  ob.last_row_cofactors.assign(n, 0);
  ex det = 0;
  for (std::size_t c = 0; c < n; ++c) {
    GiNaC::matrix minor(n - 1, n - 1);
    for (std::size_t r = 0; r + 1 < n; ++r)
      for (std::size_t cc = 0, k = 0; cc < n; ++cc) {
        if (cc == c) continue;
        minor(r, k++) = ob.O[ob.selected[r]][cc];
      }
    const ex md = n == 1 ? ex(1) : minor.determinant();
    const ex cof = ((n - 1 + c) % 2 == 0 ? 1 : -1) * md;
    ob.last_row_cofactors[c] = simplify(cof);
    det += ob.O[ob.selected[n - 1]][c] * cof;
    budget.check(expression_size(ob.last_row_cofactors[c]));
  }
  ob.det = simplify(det);
  finish_determinant(ob, x);
}

// Moves the ring and O's rows in it into ob (rows in O's order); returns ob.
Observability& keep_ring(Observability& ob, RingRows& rows) {
  if (!rows.ring) return ob;
  auto kept = std::make_shared<RingO>(RingO{std::move(*rows.ring), {}});
  for (const RowId& id : ob.rows) kept->rows.push_back(std::move(rows.grads[id.output][id.order]));
  rows = RingRows{};
  ob.ring = std::move(kept);
  return ob;
}

}  // namespace

namespace {

// Rank-only analysis (expressions false, lie_chain_in_ring kept only the ring rows): O
// triangular in the rows' zero pattern decides rank and det from the diagonal alone; true when
// it did. Otherwise O's entries are converted for the general path (false).
bool triangular_rank_of_rows(const Model& m, Observability& ob, std::vector<ExMatrix>& grads,
                             RingRows& rows) {
  if (!rows.ring || !grads[0].empty()) return false;  // the expressions are there
  if (ob.p == 1) {
    const auto& O = rows.grads[0];
    ExMatrix pattern(ob.n, ExVec(ob.n));  // 1 where O's entry is a nonzero polynomial
    for (std::size_t k = 0; k < ob.n; ++k)
      for (std::size_t c = 0; c < ob.n; ++c) pattern[k][c] = O[k][c].is_zero() ? 0 : 1;
    if (const auto cols = triangular_columns(pattern)) {
      ExVec diagonal;
      for (std::size_t k = 0; k < ob.n; ++k) {
        diagonal.push_back(rows.ring->to_ex(O[k][(*cols)[k]]));
        ob.rows.push_back({0, k});
      }
      if (triangular_rank_from_diagonal(ob, *cols, diagonal, m.sample_boxes(), m.states))
        return true;
      ob.rows.clear();
    }
  }
  for (std::size_t i = 0; i < ob.p; ++i)
    for (const auto& row : rows.grads[i]) {
      ExVec e;
      for (const auto& p : row) e.push_back(rows.ring->to_ex(p));
      grads[i].push_back(std::move(e));
    }
  return false;
}

// analyse_observability after the Lie chain: O, its rank, indices and det.
Observability& rank_and_determinant(const Model& m, Budget& budget, const ObservabilityOptions& opt,
                                    Observability& ob, std::vector<ExMatrix>& grads,
                                    RingRows& ring_rows) {
  StageScope stage(budget, "observability");
  if (triangular_rank_of_rows(m, ob, grads, ring_rows)) return ob;
  const Symbols& x = m.states;
  for (std::size_t k = 0; k < ob.n; ++k)
    for (std::size_t i = 0; i < ob.p; ++i) {
      ob.O.push_back(std::move(grads[i][k]));
      ob.rows.push_back({i, k});
    }
  const SampleBoxes boxes = m.sample_boxes();
  // Ring polynomials (Laurent only in exp bases) have no denominators.
  if (!ring_rows.ring) ob.undefined = denominators(ob.O, x);
  if (triangular_rank(ob, boxes, x)) return keep_ring(ob, ring_rows);

  bool exact = true;
  for (const auto& row : ob.O)
    for (const auto& e : row)
      if (has_transcendental(e)) exact = false;
  ob.rank_exact = exact;
  const auto best_matrix = sampled_rank(m, boxes, opt, exact, budget, ob);
  observability_indices(best_matrix, exact, ob);

  const bool full = ob.generic_rank == ob.n && ob.selected.size() == ob.n;
  bool factored = false;
  if (full && determinant_in_ring(ob, ring_rows, x, factored))
    finish_determinant(ob, x, factored);
  else if (full)
    cofactor_determinant(x, budget, ob);
  return keep_ring(ob, ring_rows);
}

// The symbolic analysis: Lie chain, then O's rank, indices and det.
Observability& symbolic_observability(const Model& m, Budget& budget,
                                      const ObservabilityOptions& opt, Observability& ob,
                                      bool expressions) {
  ob.n = m.n();
  ob.p = m.p();
  std::vector<ExMatrix> grads(ob.p);
  RingRows ring_rows;
  lie_chain(m, budget, opt, ob, grads, ring_rows, expressions);
  return rank_and_determinant(m, budget, opt, ob, grads, ring_rows);
}

// Automatic: the symbolic analysis within its work budget (opt.symbolic_work allocations),
// else the reason to decide the rank from the jets (nullopt: it completed). Only counted work
// and sizes choose; a time budget that runs out ends the stage as it would without the jets.
std::optional<std::string> symbolic_or_fallback(const Model& m, Budget& budget,
                                                const ObservabilityOptions& opt, Observability& ob,
                                                bool expressions) {
  try {
    WorkScope work(opt.symbolic_work);
    symbolic_observability(m, budget, opt, ob, expressions);
    if (!work.exceeded()) return std::nullopt;
    throw WorkBudgetExceeded();  // thrown inside, swallowed by a caller on the way
  } catch (const WorkBudgetExceeded&) {
    return fmt::format(
        "the symbolic Lie derivatives and O exceeded their work budget ({} allocations)",
        opt.symbolic_work);
  } catch (const BudgetExceeded& e) {
    if (e.stage() != "lie") throw;  // the chain's own budget stops on size only (lie_chain)
    return fmt::format("the symbolic Lie derivatives exceeded their budget ({})", e.reason());
  } catch (const std::bad_alloc&) {
    return std::string("the symbolic Lie derivatives ran out of memory");
  }
}

Observability& observability_into(const Model& m, Budget& budget, const ObservabilityOptions& opt,
                                  Observability& ob, bool expressions) {
  if (opt.rank_method == RankMethod::jets)
    return ob = observability_from_jets(m, budget, opt,
                                        "the jets rank was requested (--rank-method jets)");
  if (opt.rank_method == RankMethod::symbolic)
    return symbolic_observability(m, budget, opt, ob, expressions);
  if (const auto why = symbolic_or_fallback(m, budget, opt, ob, expressions)) {
    ob = Observability{};  // progress reports during the jets see no half-built chain
    return ob = observability_from_jets(m, budget, opt, *why);
  }
  return ob;
}

}  // namespace

Observability analyse_observability(const Model& m, Budget& budget, const ObservabilityOptions& opt,
                                    Observability* progress) {
  Observability local;
  Observability& ob = progress ? *progress : local;  // partial results survive a budget stop
  return observability_into(m, budget, opt, ob, true);
}

Observability observability_rank(const Model& m, Budget& budget, const ObservabilityOptions& opt) {
  Observability ob;
  return observability_into(m, budget, opt, ob, false);
}

namespace {

// The drift's rank, selected rows, det and its factors, without the expressions of its chain.
std::optional<Observability> rank_of_drift(const Observability& drift, std::size_t n) {
  if (drift.jets || drift.p != 1 || drift.generic_rank != n || drift.selected.size() != n)
    return std::nullopt;
  Observability ob = drift;
  ob.lie.clear();
  ob.O.clear();
  ob.ring.reset();
  return ob;
}

}  // namespace

std::optional<Observability> observability_of_triangular_form(const Model& frozen,
                                                              const TriangularForm& t,
                                                              const Observability& drift) {
  if (frozen.p() != 1) return std::nullopt;
  if (t.coordinates == TriangularForm::Coordinates::lie_derivatives)
    return rank_of_drift(drift, frozen.n());
  Observability ob;
  ob.n = frozen.n();
  ob.p = 1;
  ExVec diagonal;
  ex product = 1;
  for (std::size_t k = 0; k < ob.n; ++k) {
    if (k > 0) product *= t.a[k - 1];
    diagonal.push_back(simplify(product));
    ob.rows.push_back({0, k});
  }
  if (!triangular_rank_from_diagonal(ob, t.order, diagonal, frozen.sample_boxes(), frozen.states))
    return std::nullopt;
  return ob;
}

}  // namespace obsynth
