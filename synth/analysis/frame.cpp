#include "analysis/frame.hpp"

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

// tau_{k+1} = [-f, tau_k] = J_f tau_k - J_tau_k f in the ring, the products by FLINT;
// throws PolyOverflow.
void ring_frame(const Model& m, const CanonicalForm& cf, Budget& budget, FrameRing& fr,
                std::vector<ExVec>& frame) {
  const PolyRing& ring = *fr.ring;
  const std::size_t n = m.n();
  std::vector<Poly> f, tau;
  for (const auto& e : m.f) f.push_back(*ring.from_ex(e));
  for (const auto& e : cf.r) tau.push_back(*ring.from_ex(e));
  FlintProducts flint(ring.variables());
  std::vector<FlintProducts::Handle> f_h;
  std::vector<std::vector<FlintProducts::Handle>> Jf_h(n);
  for (std::size_t i = 0; i < n; ++i) {
    f_h.push_back(flint.add(f[i]));
    for (std::size_t j = 0; j < n; ++j) Jf_h[i].push_back(flint.add(ring.derivative(f[i], j)));
  }
  for (std::size_t k = 0; k < n; ++k) {
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

void ginac_frame(const Model& m, Budget& budget, CanonicalForm& cf) {
  ExVec minus_f;
  for (const auto& e : m.f) minus_f.push_back(-e);
  const ExMatrix Jmf = jacobian(minus_f, m.states);
  cf.frame.push_back(cf.r);
  for (std::size_t k = 1; k < m.n(); ++k) {
    cf.frame.push_back(
        lie_bracket(minus_f, Jmf, cf.frame.back(), jacobian(cf.frame.back(), m.states)));
    std::size_t size = 0;
    for (const auto& e : cf.frame.back()) size = std::max(size, expression_size(e));
    budget.check(size);
  }
}

}  // namespace

FrameRing compute_frame(const Model& m, const Observability& ob, Budget& budget,
                        CanonicalForm& cf) {
  StageScope stage(budget, "frame");
  // r = adj(O) e_n / det O: the cofactors of O's last row.
  for (std::size_t i = 0; i < m.n(); ++i)
    cf.r.push_back(ob.r.empty() ? simplify(ob.last_row_cofactors[i] / ob.det) : ob.r[i]);
  ExVec all(m.f);
  all.insert(all.end(), m.g.begin(), m.g.end());
  all.insert(all.end(), cf.r.begin(), cf.r.end());
  FrameRing fr;
  fr.ring = PolyRing::for_expressions(all, m.states);
  if (fr.ring) {
    try {
      ring_frame(m, cf, budget, fr, cf.frame);
      return fr;
    } catch (const PolyOverflow&) {
      fr = FrameRing{};
      cf.frame.clear();
    }
  }
  ginac_frame(m, budget, cf);
  return fr;
}

}  // namespace obsynth
