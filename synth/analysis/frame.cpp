#include "analysis/frame.hpp"

#include "analysis/flint_mpoly.hpp"
#include "analysis/flint_products.hpp"
#include "symbolic/lie.hpp"
#include "symbolic/symbolic.hpp"

namespace obsynth {

std::vector<std::vector<Poly>> FrameRing::jacobian(const std::vector<Poly>& v) const {
  std::vector<std::vector<Poly>> J(v.size());
  for (std::size_t i = 0; i < v.size(); ++i)
    for (std::size_t j = 0; j < ring->states(); ++j) J[i].push_back(ring->derivative(v[i], j));
  return J;
}

void FrameRing::add_field(std::vector<Poly> v) {
  jacobians.push_back(jacobian(v));
  fields.push_back(std::move(v));
}

namespace {

// tau_{k+1} = [-f, tau_k] = J_f tau_k - J_tau_k f in the ring, the products by FLINT, block
// by block from r_i = starts[i]; throws PolyOverflow.
void ring_frame(const Model& m, const std::vector<ExVec>& starts,
                const std::vector<std::size_t>& blocks, Budget& budget, FrameRing& fr,
                std::vector<ExVec>& frame) {
  const PolyRing& ring = *fr.ring;
  const std::size_t n = m.n();
  std::vector<Poly> f;
  for (const auto& e : m.f) f.push_back(*ring.from_ex(e));
  FlintProducts flint(ring.variables());
  std::vector<FlintProducts::Handle> f_h;
  std::vector<std::vector<FlintProducts::Handle>> Jf_h(n);
  for (std::size_t i = 0; i < n; ++i) {
    f_h.push_back(flint.add(f[i]));
    for (std::size_t j = 0; j < n; ++j) Jf_h[i].push_back(flint.add(ring.derivative(f[i], j)));
  }
  for (std::size_t b = 0; b < blocks.size(); ++b) {
    std::vector<Poly> tau;
    for (const auto& e : starts[b]) tau.push_back(*ring.from_ex(e));
    for (std::size_t k = 0; k < blocks[b]; ++k) {
      if (k > 0) {
        std::vector<FlintProducts::Handle> prev;
        for (const auto& p : fr.fields.back()) prev.push_back(flint.add(p));
        for (std::size_t i = 0; i < n; ++i) {
          std::vector<FlintProducts::Handle> Jprev_i;
          for (const auto& p : fr.jacobians.back()[i]) Jprev_i.push_back(flint.add(p));
          tau[i] = flint.dot_difference(Jf_h[i], prev, Jprev_i, f_h);
        }
      }
      std::size_t estimate = 0;
      for (const auto& p : tau) estimate = std::max(estimate, p.node_estimate());
      budget.check(estimate);
      fr.add_field(tau);
      ExVec t;
      std::size_t size = 0;
      for (const auto& p : tau) {
        t.push_back(ring.to_ex(p));
        size = std::max(size, expression_size(t.back()));
      }
      frame.push_back(std::move(t));
      budget.check(size);
    }
  }
}

void ginac_frame(const Model& m, const std::vector<ExVec>& starts,
                 const std::vector<std::size_t>& blocks, Budget& budget, CanonicalForm& cf) {
  ExVec minus_f;
  for (const auto& e : m.f) minus_f.push_back(-e);
  const ExMatrix Jmf = jacobian(minus_f, m.states);
  for (std::size_t b = 0; b < blocks.size(); ++b) {
    cf.frame.push_back(starts[b]);
    for (std::size_t k = 1; k < blocks[b]; ++k) {
      cf.frame.push_back(
          lie_bracket(minus_f, Jmf, cf.frame.back(), jacobian(cf.frame.back(), m.states)));
      std::size_t size = 0;
      for (const auto& e : cf.frame.back()) size = std::max(size, expression_size(e));
      budget.check(size);
    }
  }
}

// The selected rows of O, each output's top row (dL_f^{k_i - 1} h_i) moved last in turn.
std::vector<std::size_t> rows_with_last(const Observability& ob, std::size_t output) {
  std::vector<std::size_t> order, last;
  for (std::size_t r : ob.selected) {
    const RowId id = ob.rows[r];
    (id.output == output && id.order + 1 == ob.indices[output] ? last : order).push_back(r);
  }
  OBSYNTH_ASSERT(last.size() == 1, "the selected rows hold each output's top row once");
  order.push_back(last[0]);
  return order;
}

// r_i with O_sel r_i = e_(i, k_i - 1), by fraction-free elimination in FLINT when O's rows are
// ring polynomials (the cofactors of the top row, moved last, over det): nullopt otherwise.
std::optional<std::vector<ExVec>> ring_output_fields(const Observability& ob) {
  if (!ob.ring) return std::nullopt;
  const PolyRing& ring = ob.ring->ring;
  std::vector<const Poly*> all;
  for (std::size_t r : ob.selected)
    for (const auto& p : ob.ring->rows[r]) all.push_back(&p);
  const auto ctx = MPolyContext::for_polys(ring, all);
  if (!ctx) return std::nullopt;
  std::vector<ExVec> fields;
  try {
    for (std::size_t i = 0; i < ob.p; ++i) {
      std::vector<std::vector<MPoly>> a;
      for (std::size_t r : rows_with_last(ob, i)) {
        a.emplace_back();
        for (const auto& p : ob.ring->rows[r]) a.back().push_back(ctx->to_flint(p));
      }
      auto dc = det_and_last_row_cofactors(*ctx, std::move(a));
      if (!dc) return std::nullopt;
      ExVec r;
      for (const auto& c : dc->cofactors) {
        const Quotient q = reduced_quotient(*ctx, c, dc->det);
        r.push_back(ring.to_ex(ctx->from_flint(q.num)) / ring.to_ex(ctx->from_flint(q.den)));
      }
      fields.push_back(std::move(r));
    }
  } catch (const PolyOverflow&) {
    return std::nullopt;
  }
  return fields;
}

// The same with GiNaC's linear solver.
std::vector<ExVec> ginac_output_fields(const Observability& ob, Budget& budget) {
  const std::size_t n = ob.n;
  std::vector<ExVec> fields;
  for (std::size_t i = 0; i < ob.p; ++i) {
    const auto rows = rows_with_last(ob, i);
    GiNaC::matrix A(n, n), rhs(n, 1), vars(n, 1);
    for (std::size_t r = 0; r < n; ++r)
      for (std::size_t c = 0; c < n; ++c) A(r, c) = ob.O[rows[r]][c];
    rhs(n - 1, 0) = 1;
    for (std::size_t c = 0; c < n; ++c) vars(c, 0) = GiNaC::symbol("r_" + std::to_string(c));
    const GiNaC::matrix sol = A.solve(vars, rhs);
    ExVec r;
    for (std::size_t c = 0; c < n; ++c) {
      r.push_back(simplify(sol(c, 0)));
      budget.check(expression_size(r.back()));
    }
    fields.push_back(std::move(r));
  }
  return fields;
}

// r_1..r_p: the fields the blocks start from.
std::vector<ExVec> output_fields(const Observability& ob, Budget& budget) {
  if (auto fields = ring_output_fields(ob)) return *fields;
  return ginac_output_fields(ob, budget);
}

}  // namespace

FrameRing compute_frame(const Model& m, const Observability& ob, Budget& budget,
                        CanonicalForm& cf) {
  StageScope stage(budget, "frame");
  std::vector<ExVec> starts;
  if (m.p() == 1) {
    // r = adj(O) e_n / det O: the cofactors of O's last row.
    for (std::size_t i = 0; i < m.n(); ++i)
      cf.r.push_back(ob.r.empty() ? simplify(ob.last_row_cofactors[i] / ob.det) : ob.r[i]);
    starts.push_back(cf.r);
  } else {
    starts = output_fields(ob, budget);
  }
  ExVec all(m.f);
  all.insert(all.end(), m.g.begin(), m.g.end());
  for (const auto& r : starts) all.insert(all.end(), r.begin(), r.end());
  FrameRing fr;
  fr.ring = PolyRing::for_expressions(all, m.states);
  if (fr.ring) {
    try {
      ring_frame(m, starts, cf.blocks, budget, fr, cf.frame);
      return fr;
    } catch (const PolyOverflow&) {
      fr = FrameRing{};
      cf.frame.clear();
    }
  }
  ginac_frame(m, starts, cf.blocks, budget, cf);
  return fr;
}

}  // namespace obsynth
