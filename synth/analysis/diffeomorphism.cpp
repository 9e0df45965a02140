#include "analysis/diffeomorphism.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <memory>

#include "analysis/flint_products.hpp"
#include "analysis/output_function.hpp"
#include "certify/sampling.hpp"
#include "symbolic/expr_print.hpp"
#include "symbolic/integrate.hpp"
#include "symbolic/symbolic.hpp"

namespace obsynth {

using GiNaC::ex;

namespace {

// Whether every expression is defined at x0 (states substituted; inputs and parameters stay):
// no pole met by the substitution, and a numeric value that is real.
bool defined_at(const Model& m, const ExVec& x0, const std::vector<ExVec>& exprs) {
  GiNaC::exmap at;
  for (std::size_t i = 0; i < m.n(); ++i) at[m.states[i]] = x0[i];
  try {
    for (const auto& v : exprs)
      for (const auto& e : v) {
        const ex value = e.subs(at).evalf();
        if (GiNaC::is_a<GiNaC::numeric>(value) && !GiNaC::ex_to<GiNaC::numeric>(value).is_real())
          return false;
      }
  } catch (const std::domain_error&) {  // GiNaC::pole_error
    return false;
  }
  return true;
}

}  // namespace

ExVec choose_base_point(const Model& m, const std::vector<ExVec>& also_defined) {
  std::vector<ExVec> exprs = {m.field(), m.h};
  exprs.insert(exprs.end(), also_defined.begin(), also_defined.end());
  // The origin (coordinate-wise, where the box holds 0) for the simplest T; else the box's centre;
  // else deterministic points of the box, until the model and the frame are defined there.
  ExVec origin, centre;
  for (const auto& s : m.states) {
    const Interval b = m.box(s);
    centre.push_back((b.lo + b.hi) / 2);
    origin.push_back(b.lo <= 0 && b.hi >= 0 ? ex(0) : centre.back());
  }
  if (defined_at(m, origin, exprs)) return origin;
  if (defined_at(m, centre, exprs)) return centre;
  static const unsigned primes[] = {2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37};
  for (std::size_t k = 1; k <= 32; ++k) {
    ExVec x0;
    for (std::size_t i = 0; i < m.n(); ++i) {
      const Interval b = m.box(m.states[i]);
      // A rational fraction of the box (k-th Halton point, 1/64 resolution): an exact base point.
      const long q = std::lround(64 * radical_inverse(k, primes[i % 12]));
      x0.push_back(b.lo + (b.hi - b.lo) * GiNaC::numeric(q, 64));
    }
    if (defined_at(m, x0, exprs)) return x0;
  }
  return origin;  // undefined everywhere tried: the definedness stage has said where
}

namespace {

ZeroVerdict worst(ZeroVerdict a, ZeroVerdict b) {
  return static_cast<int>(a) > static_cast<int>(b) ? a : b;
}

GiNaC::exmap point_map(const Symbols& x, const ExVec& x0) {
  GiNaC::exmap mp;
  for (std::size_t i = 0; i < x.size(); ++i) mp[x[i]] = x0[i];
  return mp;
}

// What the stage works on: the model's fields, h and the frame.
struct Context {
  const Model& m;
  const CanonicalForm& cf;
  SampleBoxes boxes;
  ZeroTestOptions zero;
  GiNaC::exmap at_x0;
  ExVec y0;  // h(x0)
};

// A(h(x)) - A(h(x0)) with A' = a(y) (one output), or nullopt (and a note) when no
// antiderivative is found.
std::optional<ex> output_integral(const Context& c, const ex& a_y, std::string& note) {
  const auto A = antiderivative(a_y, c.cf.y[0]);
  if (!A) {
    note = fmt::format("no closed-form antiderivative in y of {}", to_string(a_y));
    return std::nullopt;
  }
  return A->subs(c.cf.y[0] == c.m.h[0]) - A->subs(c.cf.y[0] == c.y0[0]);
}

// A(h(x)) - A(y0) with dA/dy_q = a[q] (a closed 1-form in y), integrated along the axes: A =
// int a_1 dy_1 + int (a_2 - dA_1/dy_2)|_{y_1 = y0_1} dy_2 + ...; nullopt (and a note) when
// an antiderivative is missing.
std::optional<ex> output_potential(const Context& c, const ExVec& a, std::string& note) {
  if (a.size() == 1) return output_integral(c, a[0], note);
  const auto& y = c.cf.y;
  ex A = 0;
  GiNaC::exmap earlier;  // y_1..y_{q-1} at y0: the remainder is free of them when a is closed
  for (std::size_t q = 0; q < a.size(); ++q) {
    const ex rest = simplify((a[q] - A.diff(y[q])).subs(earlier));
    const auto Aq = antiderivative(rest, y[q]);
    if (!Aq) {
      note = fmt::format("no closed-form antiderivative in {} of {}", y[q].get_name(),
                         to_string(rest));
      return std::nullopt;
    }
    A += *Aq;
    earlier[y[q]] = c.y0[q];
  }
  GiNaC::exmap at_h, at_y0;
  for (std::size_t q = 0; q < a.size(); ++q) {
    at_h[y[q]] = c.m.h[q];
    at_y0[y[q]] = c.y0[q];
  }
  return A.subs(at_h) - A.subs(at_y0);
}

// z_{i,k_i} = h_i - h_i(x0); down each block, z_{i,m-1} = L_f z_{i,m} - l_{i,m}(y) with
// dl_{i,m}/dy_q = L_{tau_{q,k_q}} L_f z_{i,m} (functions of y when the conditions hold), the
// constant fixing T(x0) = 0.
enum class Outcome { closed, no_closed_form, outside_ring };

Outcome ginac_T(const Context& c, Budget& budget, ExVec& T, std::string& note) {
  const CanonicalForm& cf = c.cf;
  const Symbols& x = c.m.states;
  T.assign(c.m.n(), 0);
  for (std::size_t b = 0; b < cf.outputs(); ++b) {
    const std::size_t end = cf.block_end(b);
    T[end] = simplify(c.m.h[b] - c.y0[b]);
    for (std::size_t i = end; i > cf.block_start(b); --i) {
      const ex LfTi = lie_derivative(T[i], c.m.f, x);
      ExVec a_y;
      for (std::size_t q = 0; q < cf.outputs(); ++q) {
        const ex a_x = lie_derivative(LfTi, cf.frame[cf.block_end(q)], x);
        const auto a = express_in_outputs(a_x, c.m.h, x, cf.y, cf.base_point, c.boxes);
        if (!a) {
          note = fmt::format("L_{} L_f T_{} = {} could not be written as a function of y",
                             cf.tau_name(cf.block_end(q)), i + 1, to_string(a_x));
          return Outcome::no_closed_form;
        }
        a_y.push_back(*a);
      }
      const auto potential = output_potential(c, a_y, note);
      if (!potential) return Outcome::no_closed_form;
      T[i - 1] = simplify(LfTi - *potential - simplify(LfTi.subs(c.at_x0)));
      budget.check(expression_size(T[i - 1]));
    }
  }
  return Outcome::closed;
}

// The same construction in the ring: f, the frame and T stay polynomials.
struct RingFields {
  const PolyRing& ring;
  std::vector<Poly> f, F;                       // f and f + g
  const std::vector<std::vector<Poly>>& frame;  // tau_1..tau_n
  OutputFunction in_output;
  std::shared_ptr<FlintProducts> flint;  // for products of two large operands
  Poly lie(const Poly& p, const std::vector<Poly>& field) const {
    std::vector<Poly> grad;
    std::size_t largest = 0;
    for (std::size_t j = 0; j < ring.states(); ++j) {
      grad.push_back(ring.derivative(p, j));
      largest = std::max(largest, field[j].terms.size());
    }
    // The hash map costs one insertion per pair of terms; FLINT multiplies packed exponents.
    if (p.terms.size() * largest < 100000) return PolyRing::dot(grad, field);
    std::vector<FlintProducts::Handle> g, v;
    for (std::size_t j = 0; j < grad.size(); ++j) {
      g.push_back(flint->add(grad[j]));
      v.push_back(flint->add(field[j]));
    }
    return flint->dot_difference(g, v, {}, {});
  }
};

Outcome ring_T(const Context& c, const RingFields& r, Budget& budget, std::vector<Poly>& T,
               std::string& note) {
  const std::size_t n = c.m.n();
  T.assign(n, Poly{});
  const auto hn = r.ring.from_ex(c.m.h[0] - c.y0[0]);
  if (!hn) return Outcome::outside_ring;
  T[n - 1] = *hn;
  for (std::size_t i = n - 1; i >= 1; --i) {
    const Poly LfTi = r.lie(T[i], r.f);
    const auto a_y = r.in_output(r.lie(LfTi, r.frame[n - 1]));
    if (!a_y) {
      note = fmt::format("L_tau_n L_f T_{} could not be written as a function of y", i + 1);
      return Outcome::no_closed_form;
    }
    const auto integral = output_integral(c, a_y->value, note);
    if (!integral) return Outcome::no_closed_form;
    const auto I = r.ring.from_ex(*integral + simplify(r.ring.to_ex(LfTi).subs(c.at_x0)));
    if (!I) return Outcome::outside_ring;
    T[i - 1] = LfTi;
    PolyRing::subtract_from(T[i - 1], *I);
    budget.check(T[i - 1].node_estimate());
  }
  return Outcome::closed;
}

// dT/dx [tau] = I, entry by entry, exactly in the ring (the zero test for what the ring
// leaves nonzero, such as sin^2 + cos^2 - 1).
ZeroVerdict verify_T_ring(const Context& c, const RingFields& r, const std::vector<Poly>& T) {
  const std::size_t n = c.m.n();
  ZeroVerdict v = ZeroVerdict::proved;
  for (std::size_t i = 0; i < n && v != ZeroVerdict::nonzero; ++i) {
    std::vector<Poly> grad;
    for (std::size_t k = 0; k < n; ++k) grad.push_back(r.ring.derivative(T[i], k));
    for (std::size_t j = 0; j < n; ++j) {
      Poly acc = PolyRing::dot(grad, r.frame[j]);
      if (i == j) PolyRing::subtract_from(acc, *r.ring.from_ex(1));
      if (!acc.is_zero()) v = worst(v, zero_test(r.ring.to_ex(acc), c.boxes, c.zero));
    }
  }
  return v;
}

ZeroVerdict verify_T_ginac(const Context& c, const ExVec& T) {
  const std::size_t n = c.m.n();
  ZeroVerdict v = ZeroVerdict::proved;
  for (std::size_t i = 0; i < n && v != ZeroVerdict::nonzero; ++i) {
    const ExVec dTi = gradient(T[i], c.m.states);
    for (std::size_t j = 0; j < n; ++j) {
      ex acc = 0;
      for (std::size_t k = 0; k < n; ++k) acc += dTi[k] * c.cf.frame[j][k];
      v = worst(v, zero_test(simplify(acc - (i == j ? 1 : 0)), c.boxes, c.zero));
    }
  }
  return v;
}

// l_i = L_{f+g} T_i - T_{i-1} as a function of (u, y), checked by l(u, h(x)) = that.
void ring_l(const RingFields& r, const std::vector<Poly>& T, CanonicalForm& cf) {
  ZeroVerdict lv = ZeroVerdict::proved;
  ExVec l;
  for (std::size_t i = 0; i < T.size(); ++i) {
    Poly li_x = r.lie(T[i], r.F);
    if (i > 0) PolyRing::subtract_from(li_x, T[i - 1]);
    const auto li = r.in_output(li_x);
    if (!li) {
      cf.l_note = fmt::format("l_{} = {} is not a function of (u, y)", i + 1,
                              to_string(r.ring.to_ex(li_x)));
      cf.l_verdict = ZeroVerdict::nonzero;
      return;
    }
    lv = worst(lv, li->verdict);
    l.push_back(li->value);
  }
  cf.l = l;
  cf.l_verdict = lv;
  cf.l_kind = Availability::symbolic;
  cf.l_note = "l(u, h(x)) = L_{f+g} T - A T verified by substitution";
}

void ginac_l(const Context& c, CanonicalForm& cf) {
  const Symbols& x = c.m.states;
  const ExVec F = c.m.field();
  GiNaC::exmap y_to_h;
  for (std::size_t q = 0; q < cf.y.size(); ++q) y_to_h[cf.y[q]] = c.m.h[q];
  ZeroVerdict lv = ZeroVerdict::proved;
  ExVec l;
  for (std::size_t i = 0; i < cf.T.size(); ++i) {
    const bool chained = i != cf.block_start(cf.block_of(i));
    const ex li_x = simplify(lie_derivative(cf.T[i], F, x) - (chained ? cf.T[i - 1] : ex(0)));
    const auto li = express_in_outputs(li_x, c.m.h, x, cf.y, cf.base_point, c.boxes);
    if (!li) {
      cf.l_note = fmt::format("l_{} = {} is not a function of (u, y)", i + 1, to_string(li_x));
      cf.l_verdict = ZeroVerdict::nonzero;
      return;
    }
    // Independent check: l_i(u, h(x)) equals the x-expression.
    lv = worst(lv, zero_test(simplify(li->subs(y_to_h) - li_x), c.boxes, c.zero));
    if (lv == ZeroVerdict::nonzero) {
      cf.l_note = fmt::format("l_{}(u, h(x)) differs from L_{{f+g}} T_{} - T_{}", i + 1, i + 1, i);
      cf.l_verdict = lv;
      return;
    }
    l.push_back(*li);
  }
  cf.l = l;
  cf.l_verdict = lv;
  cf.l_kind = Availability::symbolic;
  cf.l_note = "l(u, h(x)) = L_{f+g} T - A T verified by substitution";
}

// The ring's view of the stage, when f, g, h and the frame all live in it.
std::optional<RingFields> ring_fields(const Context& c, const FrameRing& fr) {
  // One output: the ring's output function solves y = h(x) along a line.
  if (!fr.ring || fr.fields.size() <= c.m.n() || c.m.p() != 1) return std::nullopt;
  const PolyRing& ring = *fr.ring;
  std::vector<Poly> f, F;
  for (std::size_t i = 0; i < c.m.n(); ++i) {
    const auto fi = ring.from_ex(c.m.f[i]);
    if (!fi) return std::nullopt;
    f.push_back(*fi);
    F.push_back(*fi);
    PolyRing::add_to(F.back(), fr.fields[c.m.n()][i]);  // + g_i
  }
  return RingFields{
      ring,
      std::move(f),
      std::move(F),
      fr.fields,
      OutputFunction(ring, c.m.h[0], c.m.states, c.cf.y[0], c.cf.base_point, c.boxes, c.zero),
      std::make_shared<FlintProducts>(ring.variables())};
}

void set_T(ExVec T, ZeroVerdict v, CanonicalForm& cf) {
  OBSYNTH_ASSERT(v != ZeroVerdict::nonzero, "constructed T does not satisfy dT/dx [tau] = I");
  cf.T = std::move(T);
  cf.T_verdict = v;
  cf.T_kind = Availability::symbolic;
  cf.T_note = fmt::format("dT/dx [tau] = I {}",
                          v == ZeroVerdict::proved ? "proved" : "verified numerically");
}

// The ring path; false when the model leaves the ring on the way (GiNaC takes over).
bool ring_diffeomorphism(const Context& c, const FrameRing& fr, Budget& budget, CanonicalForm& cf) {
  const auto r = ring_fields(c, fr);
  if (!r) return false;
  std::vector<Poly> T;
  try {
    const Outcome o = ring_T(c, *r, budget, T, cf.T_note);
    if (o == Outcome::outside_ring) return false;
    if (o == Outcome::no_closed_form) return true;
    ExVec Tx;
    for (const auto& p : T) Tx.push_back(r->ring.to_ex(p));
    set_T(std::move(Tx), verify_T_ring(c, *r, T), cf);
    ring_l(*r, T, cf);
  } catch (const PolyOverflow&) {
    cf.T_note.clear();
    return false;
  }
  return true;
}

void ginac_diffeomorphism(const Context& c, Budget& budget, CanonicalForm& cf) {
  ExVec T;
  if (ginac_T(c, budget, T, cf.T_note) != Outcome::closed) return;
  const ZeroVerdict v = verify_T_ginac(c, T);
  set_T(std::move(T), v, cf);
  ginac_l(c, cf);
}

}  // namespace

void build_diffeomorphism(const Model& m, const FrameRing& fr, Budget& budget,
                          const CanonicalOptions& opt, CanonicalForm& cf) {
  cf.base_point = choose_base_point(m, cf.frame);
  const GiNaC::exmap at_x0 = point_map(m.states, cf.base_point);
  ExVec y0;
  for (const auto& h : m.h) y0.push_back(simplify(h.subs(at_x0)));
  const Context c{m, cf, m.sample_boxes(), opt.zero, at_x0, std::move(y0)};
  if (!ring_diffeomorphism(c, fr, budget, cf)) ginac_diffeomorphism(c, budget, cf);
  if (cf.T_kind != Availability::symbolic) {
    cf.T_kind = Availability::numeric;
    cf.T_note += "; T is to be evaluated numerically (quadrature of the closed 1-form [tau]^-1 dx)";
    cf.l_note = "needs T in closed form";
  } else if (cf.l_kind != Availability::symbolic && cf.l_note.empty()) {
    cf.l_note = "l is not a function of (u, y)";
  }
}

}  // namespace obsynth
