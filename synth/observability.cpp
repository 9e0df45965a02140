#include "observability.hpp"

#include <algorithm>
#include <set>

#include "expr_print.hpp"
#include "symbolic.hpp"
#include "zero_test.hpp"

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

ExVec dependent_factors(const ex& e, const Symbols& x) {
  GiNaC::exmap repl;
  const ex num = GiNaC::numer(GiNaC::normal(e));
  const ex poly = num.to_polynomial(repl);
  ex fac = GiNaC::factor(poly);
  GiNaC::exmap back;
  for (const auto& [k, v] : repl) back[k] = v;
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
    if (GiNaC::is_a<GiNaC::function>(g) && GiNaC::ex_to<GiNaC::function>(g).get_name() == "exp") return;
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

namespace {

ExVec denominators(const ExMatrix& O, const Symbols& x) {
  std::map<std::string, ex> unique;
  for (const auto& row : O)
    for (const auto& e : row) {
      if (!has_denominator_in(e, x)) continue;  // cheap structural test first
      for (const auto& f : dependent_factors(GiNaC::denom(e), x))
        unique.emplace(to_string(f), f);
    }
  ExVec out;
  for (auto& [s, f] : unique) out.push_back(f);
  return out;
}

struct PointMatrix {
  std::vector<std::vector<numeric>> a;
  bool valid = true;
};

PointMatrix evaluate_matrix(const ExMatrix& O, const GiNaC::exmap& pt, bool exact, int digits) {
  PointMatrix pm;
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
      } else if (!evaluate_real(e, pt, digits, v)) {
        pm.valid = false;
        return pm;
      }
      r.push_back(v);
    }
    pm.a.push_back(std::move(r));
  }
  return pm;
}

}  // namespace

Observability analyse_observability(const Model& m, Budget& budget, const ObservabilityOptions& opt) {
  Observability ob;
  ob.n = m.n();
  ob.p = m.p();
  const Symbols& x = m.states;
  {
    StageScope stage(budget, "lie");
    for (const auto& h : m.h) ob.lie.push_back(lie_derivative_chain(h, m.f, x, ob.n, &budget));
  }
  StageScope stage(budget, "observability");
  for (std::size_t k = 0; k < ob.n; ++k)
    for (std::size_t i = 0; i < ob.p; ++i) {
      ExVec row = gradient(ob.lie[i][k], x);
      for (auto& e : row) e = simplify(e);
      ob.O.push_back(std::move(row));
      ob.rows.push_back({i, k});
      budget.check();
    }

  bool exact = true;
  for (const auto& row : ob.O)
    for (const auto& e : row)
      if (has_transcendental(e)) exact = false;
  for (const auto& s : m.free_params()) (void)s;  // free parameters are sampled like states
  ob.rank_exact = exact;

  // Symbols to sample: states and free parameters (O does not depend on u).
  std::vector<GiNaC::symbol> syms(x);
  for (const auto& s : m.free_params()) syms.push_back(s);
  const SampleBoxes boxes = SampleBoxes::from_model(m);
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
  }
  if (used == 0)
    throw UserError(SourceLoc{m.file, 0, 0},
                    "the observability matrix is undefined at every sampled point of the domain; "
                    "declare a 'domain' where the model is defined");

  // Observability indices: add rows in k-major order, keeping those that raise the rank.
  ob.indices.assign(ob.p, 0);
  std::vector<bool> stopped(ob.p, false);
  std::vector<std::vector<numeric>> acc;
  for (std::size_t r = 0; r < ob.O.size(); ++r) {
    const std::size_t i = ob.rows[r].output;
    if (stopped[i]) continue;
    acc.push_back(best_matrix[r]);
    if (numeric_rank(acc, exact) == acc.size()) {
      ob.selected.push_back(r);
      ++ob.indices[i];
    } else {
      acc.pop_back();
      stopped[i] = true;
    }
  }

  ob.undefined = denominators(ob.O, x);
  if (ob.generic_rank == ob.n && ob.selected.size() == ob.n) {
    // det by cofactor expansion along the last selected row; the cofactors are adj(O) e_n.
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
    ob.rank_drop = dependent_factors(ob.det, x);
    for (const auto& f : dependent_factors(GiNaC::denom(GiNaC::normal(ob.det)), x)) {
      const std::string s = to_string(f);
      bool seen = false;
      for (const auto& u : ob.undefined) seen |= to_string(u) == s;
      if (!seen) ob.undefined.push_back(f);
    }
  }
  return ob;
}

}  // namespace obsynth
