#include "designs/observers.hpp"

#include <fmt/format.h>

#include "symbolic/expr_print.hpp"
#include "symbolic/lie.hpp"
#include "symbolic/symbolic.hpp"

namespace obsynth {

using GiNaC::ex;
using GiNaC::numeric;

const char* realisation_name(Realisation r) {
  return r == Realisation::z ? "z" : "x";
}

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

CanonicalDesign design_canonical(const Analysis& a, const CanonicalDesignOptions& opt) {
  const Model& m = a.model;
  const CanonicalForm& cf = a.canonical;
  const std::size_t n = m.n();
  if (!cf.applicable)
    throw UserError(SourceLoc{m.file, 0, 0},
                    "method 'canonical' does not apply: " + cf.not_applicable);
  if (!cf.linearizable) {
    std::string failing;
    for (const auto& b : cf.drift)
      if (!b.holds()) failing += fmt::format(" [tau_{}, tau_{}] != 0;", b.i, b.j);
    for (const auto& b : cf.input)
      if (!b.holds()) failing += fmt::format(" [g, tau_{}] != 0;", b.j);
    throw UserError(
        SourceLoc{m.file, 0, 0},
        "method 'canonical' does not apply: the model is not linearizable by output injection:" +
            failing);
  }
  if (cf.l_kind != Availability::symbolic)
    throw UserError(SourceLoc{m.file, 0, 0},
                    "method 'canonical' needs l(u, y) in closed form: " + cf.l_note);
  CanonicalDesign d;
  d.poles = opt.poles.empty() ? default_poles(n) : opt.poles;
  if (d.poles.size() != n)
    throw UserError(SourceLoc{}, fmt::format("--poles: {} poles given, the model has n = {} states",
                                             d.poles.size(), n));
  for (const auto& q : d.poles)
    if (!q.is_negative())
      throw UserError(
          SourceLoc{},
          fmt::format("--poles: pole {} is not in the open left half-plane", to_string(q)));
  d.K = gains_from_poles(d.poles);
  const bool T_closed = cf.T_kind == Availability::symbolic;
  const bool Tinv_closed = cf.T_inverse_kind == Availability::symbolic;
  if (opt.realisation) {
    d.realisation = *opt.realisation;
    d.realisation_reason = "chosen with --realisation";
    if (d.realisation == Realisation::z && !T_closed)
      throw UserError(SourceLoc{}, "--realisation z needs T in closed form: " + cf.T_note);
  } else if (T_closed && Tinv_closed) {
    d.realisation = Realisation::z;
    d.realisation_reason =
        "T and T^-1 are closed-form: the z realisation integrates a linear system";
  } else {
    d.realisation = Realisation::x;
    d.realisation_reason = T_closed
                               ? "T^-1 has no closed form: the x realisation needs no inverse"
                               : "T has no closed form: the x realisation needs neither T nor T^-1";
  }
  d.newton_inverse = d.realisation == Realisation::z && !Tinv_closed;
  GiNaC::exmap at_x0;
  if (!cf.base_point.empty())
    for (std::size_t i = 0; i < n; ++i) at_x0[m.states[i]] = cf.base_point[i];
  d.y0 = simplify(m.h[0].subs(at_x0));

  // z realisation: with u, y held over a step, c = l(u,y) + K (y - y0) is constant and
  // zh' = A zh - K zh_n + c.
  for (std::size_t i = 0; i < n; ++i) {
    d.zh.push_back(GiNaC::symbol(fmt::format("zh{}", i + 1)));
    d.c.push_back(GiNaC::symbol(fmt::format("c{}", i + 1)));
  }
  for (std::size_t i = 0; i < n; ++i)
    d.z_rhs.push_back((i ? ex(d.zh[i - 1]) : ex(0)) - d.K[i] * d.zh[n - 1] + d.c[i]);

  // x realisation (needs the frame and l; not T).
  if (d.realisation == Realisation::x) {
    const ex yhat = m.h[0];
    const ExVec F = m.field();
    std::vector<ex> v(n);
    GiNaC::exmap y_to_yhat{{cf.y, yhat}};
    for (std::size_t i = 0; i < n; ++i)
      v[i] = cf.l[i] - cf.l[i].subs(y_to_yhat) + d.K[i] * (cf.y - yhat);
    for (std::size_t r = 0; r < n; ++r) {
      ex acc = F[r];
      for (std::size_t k = 0; k < n; ++k) acc += cf.frame[k][r] * v[k];
      d.x_rhs.push_back(acc);
    }
  }
  return d;
}

PerfectDesign design_perfect(const Analysis& a) {
  const Model& m = a.model;
  const CanonicalForm& cf = a.canonical;
  const std::size_t n = m.n();
  if (!cf.applicable || !cf.linearizable)
    throw UserError(
        SourceLoc{m.file, 0, 0},
        "method 'perfect' needs the observer canonical form (seed 003 Lemma 1): " +
            (cf.applicable ? std::string("the bracket conditions fail") : cf.not_applicable));
  if (cf.l_kind != Availability::symbolic || cf.T_kind != Availability::symbolic)
    throw UserError(SourceLoc{m.file, 0, 0},
                    "method 'perfect' needs T and l in closed form: " +
                        (cf.T_kind != Availability::symbolic ? cf.T_note : cf.l_note));
  PerfectDesign d;
  for (std::size_t k = 0; k < n; ++k) d.y_jet.push_back(GiNaC::symbol(fmt::format("y_d{}", k)));
  for (const auto& u : m.inputs) {
    std::vector<GiNaC::symbol> jet;
    for (std::size_t k = 0; k + 1 < std::max<std::size_t>(n, 2); ++k)
      jet.push_back(GiNaC::symbol(fmt::format("{}_d{}", u.get_name(), k)));
    d.u_jet.push_back(jet);
  }
  // Total time derivative on functions of the jets.
  auto D = [&](const ex& phi) {
    ex acc = 0;
    for (std::size_t k = 0; k + 1 < d.y_jet.size(); ++k)
      acc += phi.diff(d.y_jet[k]) * d.y_jet[k + 1];
    for (const auto& jet : d.u_jet)
      for (std::size_t k = 0; k + 1 < jet.size(); ++k) acc += phi.diff(jet[k]) * jet[k + 1];
    return simplify(acc);
  };
  GiNaC::exmap at_x0;
  for (std::size_t i = 0; i < n; ++i) at_x0[m.states[i]] = cf.base_point[i];
  const ex y0 = simplify(m.h[0].subs(at_x0));
  GiNaC::exmap to_jets{{cf.y, d.y_jet[0]}};
  for (std::size_t j = 0; j < m.m(); ++j) to_jets[m.inputs[j]] = d.u_jet[j][0];
  d.z.assign(n, 0);
  d.z[n - 1] = d.y_jet[0] - y0;
  for (std::size_t i = n - 1; i >= 1; --i) d.z[i - 1] = simplify(D(d.z[i]) - cf.l[i].subs(to_jets));
  if (cf.T_inverse_kind == Availability::symbolic) {
    GiNaC::exmap zs;
    for (std::size_t i = 0; i < n; ++i) zs[cf.z[i]] = d.z[i];
    for (const auto& e : cf.T_inverse) d.x.push_back(simplify(e.subs(zs)));
  } else {
    d.newton_inverse = true;
  }
  const ExVec& used = d.newton_inverse ? d.z : d.x;
  for (std::size_t k = 0; k < d.y_jet.size(); ++k)
    for (const auto& e : used)
      if (e.has(d.y_jet[k])) d.y_order = std::max(d.y_order, k);
  d.input_orders.assign(m.m(), 0);
  for (std::size_t j = 0; j < m.m(); ++j)
    for (std::size_t k = 0; k < d.u_jet[j].size(); ++k)
      for (const auto& e : used)
        if (e.has(d.u_jet[j][k])) d.input_orders[j] = std::max(d.input_orders[j], k);
  return d;
}

}  // namespace obsynth
