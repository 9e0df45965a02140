#include "analysis/output_transformation.hpp"

#include <fmt/format.h>

#include <functional>

#include "analysis/inverse.hpp"
#include "analysis/triangular_form.hpp"
#include "symbolic/expr_print.hpp"
#include "symbolic/integrate.hpp"
#include "symbolic/lie.hpp"
#include "symbolic/symbolic.hpp"
#include "symbolic/zero_test.hpp"

namespace obsynth {

using GiNaC::ex;

namespace {

constexpr std::size_t kMaxStates = 6;
constexpr std::size_t kMaxNodes = 4000;  // per frame or bracket component

// Fields in x and the jets P_j = phi^(j)(h(x)): the Jacobian by the chain rule,
// d P_j / d x_i = P_{j+1} dh/dx_i.
struct JetCalculus {
  const Symbols& x;
  ExVec dh;                      // dh/dx_i
  std::vector<GiNaC::symbol> P;  // P_0 .. P_n

  ExMatrix jacobian(const ExVec& v) const {
    ExMatrix J(v.size(), ExVec(x.size()));
    for (std::size_t r = 0; r < v.size(); ++r)
      for (std::size_t i = 0; i < x.size(); ++i) {
        ex d = v[r].diff(x[i]);
        for (std::size_t j = 0; j + 1 < P.size(); ++j)
          if (v[r].has(P[j])) d += v[r].diff(P[j]) * P[j + 1] * dh[i];
        J[r][i] = d;
      }
    return J;
  }
  ExVec bracket(const ExVec& a, const ExVec& b) const {
    return lie_bracket(a, jacobian(a), b, jacobian(b));
  }
};

// The bracket with P_j = P_0 Q_j (Q_0 = 1), divided by P_0^2 (it is a quadratic form in the P).
ExVec in_ratios(const ExVec& b, const JetCalculus& jc, const std::vector<GiNaC::symbol>& Q) {
  GiNaC::exmap to_q;
  for (std::size_t j = 1; j < jc.P.size(); ++j) to_q[jc.P[j]] = jc.P[0] * Q[j];
  ExVec out;
  for (const auto& e : b)
    out.push_back(simplify(GiNaC::expand(e.subs(to_q)) / (jc.P[0] * jc.P[0])));
  return out;
}

std::size_t highest_ratio(const ExVec& v, const std::vector<GiNaC::symbol>& Q) {
  std::size_t top = 0;
  for (std::size_t j = 1; j < Q.size(); ++j)
    for (const auto& e : v)
      if (e.has(Q[j])) top = j;
  return top;
}

// c from A + c B = 0 (componentwise, B not identically zero), or nullopt.
std::optional<ex> ratio_from(const ExVec& v, const GiNaC::symbol& q1) {
  for (const auto& e : v) {
    const ex x = GiNaC::expand(e);
    if (x.degree(q1) > 1) return std::nullopt;
    const ex B = simplify(x.coeff(q1, 1));
    if (B.is_zero()) continue;
    return simplify(-x.coeff(q1, 0) / B);
  }
  return std::nullopt;
}

// e with `rule` applied to every subexpression, innermost first.
ex rewrite_bottom_up(const ex& e, const std::function<ex(const ex&)>& rule) {
  struct Rewrite : GiNaC::map_function {
    const std::function<ex(const ex&)>& rule;
    explicit Rewrite(const std::function<ex(const ex&)>& r) : rule(r) {}
    ex operator()(const ex& x) override { return rule(x.map(*this)); }
  } rewrite(rule);
  return rewrite(e);
}

bool is_call(const ex& e, const char* name) {
  return GiNaC::is_a<GiNaC::function>(e) && GiNaC::ex_to<GiNaC::function>(e).get_name() == name;
}

ex fold_exp_log(const ex& e);

// c(x) as C(y) with c(x) = C(h(x)): h solved for one state it depends on, substituted; nullopt
// when some state is left (c is not a function of the output).
std::optional<ex> as_function_of_output(const ex& c, const Model& m, const GiNaC::symbol& y) {
  for (const auto& xk : m.states) {
    if (!m.h[0].has(xk)) continue;
    const auto xk_of_y = solve_for(m.h[0] - y, xk);
    if (!xk_of_y) continue;
    const ex C = simplify(fold_exp_log(c.subs(xk == *xk_of_y)));
    if (!depends_on(C, m.states)) return C;
  }
  return std::nullopt;
}

// exp of a sum of multiples of logarithms and other terms: exp(k log g) -> g^k, so that
// exp(-integral c) of a rational c stays algebraic (the integrator's class).
ex exp_of(const ex& e) {
  const ex x = GiNaC::expand(e);
  if (GiNaC::is_a<GiNaC::add>(x)) {
    ex out = 1;
    for (std::size_t k = 0; k < x.nops(); ++k) out *= exp_of(x.op(k));
    return out;
  }
  if (is_call(x, "log")) return x.op(0);
  if (GiNaC::is_a<GiNaC::mul>(x)) {
    ex coeff = 1, log_arg;
    bool one_log = false;
    for (std::size_t k = 0; k < x.nops(); ++k) {
      const ex f = x.op(k);
      if (!one_log && is_call(f, "log")) {
        log_arg = f.op(0);
        one_log = true;
      } else {
        coeff *= f;
      }
    }
    if (one_log && GiNaC::is_a<GiNaC::numeric>(coeff)) return GiNaC::pow(log_arg, coeff);
  }
  return GiNaC::exp(x);
}

// exp(k log g) -> g^k everywhere in e (h solved for a state often leaves exp(-log(y))).
ex fold_exp_log(const ex& e) {
  return rewrite_bottom_up(e, [](const ex& x) { return is_call(x, "exp") ? exp_of(x.op(0)) : x; });
}

// log(exp(a)) -> a (a real): psi = log composed with an exponential sensor.
ex fold_log_exp(const ex& e) {
  return rewrite_bottom_up(e, [](const ex& x) {
    return is_call(x, "log") && is_call(x.op(0), "exp") ? x.op(0).op(0) : x;
  });
}

// (b^(2k))^q -> b^(2kq): the integrator writes log(b^2) / 2 for log|b|. psi' is needed only up
// to a constant factor on the output's range, which is connected and where b has no zero (phi'
// / phi = c is finite there), so the sign of b is constant there and drops out.
ex fold_even_roots(const ex& e) {
  return rewrite_bottom_up(e, [](const ex& x) {
    if (!GiNaC::is_a<GiNaC::power>(x) || !GiNaC::is_a<GiNaC::power>(x.op(0))) return x;
    const ex k = x.op(0).op(1);
    return k.info(GiNaC::info_flags::even) ? GiNaC::pow(x.op(0).op(0), k * x.op(1)) : x;
  });
}

}  // namespace

// Several outputs: y_i = s_i(x_k) of one state, not affine, solved for x_k (exp, log, atan,
// tanh, roots: analysis/inverse.hpp) gives psi_i = s_i^-1.
OutputTransformationCandidate sensor_inversions(const Model& m, const CanonicalForm& cf) {
  OutputTransformationCandidate out;
  ExVec psi;
  std::vector<std::string> done;
  for (std::size_t i = 0; i < m.p(); ++i) {
    psi.push_back(cf.y[i]);
    std::vector<GiNaC::symbol> read;
    for (const auto& x : m.states)
      if (m.h[i].has(x)) read.push_back(x);
    if (read.size() != 1 || !m.h[i].diff(read[0]).has(read[0])) continue;  // affine already
    const auto inverse = solve_for(m.h[i] - cf.y[i], read[0], true);
    if (!inverse || depends_on(*inverse, m.states)) continue;
    psi.back() = *inverse;
    done.push_back(fmt::format("y{} = {} inverted: psi_{} = {}", i + 1, to_string(m.h[i]), i + 1,
                               to_string(*inverse)));
  }
  if (done.empty()) {
    out.how =
        "several outputs: no output reads a single state through an invertible nonlinear map "
        "(the jets construction is for one output)";
    return out;
  }
  out.psi = psi;
  out.how = fmt::format("several outputs, each sensor's map inverted: {}", fmt::join(done, "; "));
  return out;
}

OutputTransformationCandidate output_transformation_candidate(const Model& m,
                                                              const CanonicalForm& cf) {
  OutputTransformationCandidate out;
  const std::size_t n = m.n();
  if (!cf.applicable || cf.y.size() != m.p()) {
    out.how = "the canonical form does not apply";
    return out;
  }
  if (m.p() > 1) return sensor_inversions(m, cf);
  if (cf.r.size() != n) {
    out.how = "no dual field r";
    return out;
  }
  if (n > kMaxStates) {
    out.how = fmt::format(
        "not searched above {} states (the frame in the jets of phi grows "
        "with every bracket)",
        kMaxStates);
    return out;
  }
  JetCalculus jc{m.states, {}, {}};
  for (const auto& xi : m.states) jc.dh.push_back(m.h[0].diff(xi));
  std::vector<GiNaC::symbol> Q;
  for (std::size_t j = 0; j <= n; ++j) {
    jc.P.emplace_back(fmt::format("P_{}", j));
    Q.emplace_back(fmt::format("Q_{}", j));
  }
  ExVec minus_f;
  for (const auto& e : m.f) minus_f.push_back(-e);
  std::vector<ExVec> frame;
  ExVec t;
  for (const auto& e : cf.r) t.push_back(jc.P[0] * e);
  frame.push_back(t);
  for (std::size_t k = 1; k < n; ++k) {
    frame.push_back(jc.bracket(minus_f, frame.back()));
    for (const auto& e : frame.back())
      if (expression_size(e) > kMaxNodes) {
        out.how = fmt::format("not searched: tau~_{} exceeds {} nodes", k + 1, kMaxNodes);
        return out;
      }
  }
  // Brackets in order of j - i, then i: a component free of the ratios must vanish whatever psi;
  // the first component that involves phi'/phi alone, linearly, fixes c.
  std::optional<ex> c;
  std::string from;
  for (std::size_t gap = 1; gap < n && !c; ++gap)
    for (std::size_t i = 0; i + gap < n && !c; ++i) {
      const ExVec b = in_ratios(jc.bracket(frame[i], frame[i + gap]), jc, Q);
      for (const auto& e : b)
        if (expression_size(e) > kMaxNodes) {
          out.how = fmt::format("not searched further: [tau~_{}, tau~_{}] exceeds {} nodes", i + 1,
                                i + gap + 1, kMaxNodes);
          return out;
        }
      const std::string name = fmt::format("[tau~_{}, tau~_{}]", i + 1, i + gap + 1);
      for (std::size_t k = 0; k < b.size() && !c; ++k) {
        const std::size_t top = highest_ratio({b[k]}, Q);
        if (top == 0 && !b[k].is_zero()) {
          out.how = fmt::format(
              "component {} of {} does not involve psi and is not zero ({}): no output "
              "transformation helps",
              k + 1, name, to_string(b[k]));
          return out;
        }
        if (top == 1) c = ratio_from({b[k]}, Q[1]);
        if (c) from = fmt::format("component {} of {}", k + 1, name);
      }
    }
  if (!c) {
    out.how = "no component of the transformed brackets involves phi'/phi alone, linearly";
    return out;
  }
  const GiNaC::symbol& y = cf.y[0];
  const auto C = as_function_of_output(*c, m, y);
  if (!C) {
    out.how =
        fmt::format("{} gives phi'/phi = {}, which is not a function of y", from, to_string(*c));
    return out;
  }
  out.c = *C;
  const Integral Phi = integrate(*C, y);
  if (!Phi.value) {
    out.how = fmt::format("phi'/phi = {} (from {}) has no antiderivative found: {}", to_string(*C),
                          from, Phi.reason);
    return out;
  }
  const ex dpsi = simplify(fold_even_roots(exp_of(-*Phi.value)));
  const Integral psi = integrate(dpsi, y);
  if (!psi.value) {
    out.how = fmt::format("psi' = {} (phi'/phi = {} from {}) has no antiderivative found: {}",
                          to_string(dpsi), to_string(*C), from, psi.reason);
    return out;
  }
  out.psi = ExVec{simplify(*psi.value)};
  out.how = fmt::format("{} gives phi'/phi = {} (phi = 1/psi'), so psi' = {}", from, to_string(*C),
                        to_string(dpsi));
  return out;
}

// psi(h) when its gradient is constant: the affine map it is (psi inverts a sensor's
// nonlinearity, y = s(x_k) with psi = s^-1 up to scale), which the later stages can solve for a
// state. Otherwise psi(h) itself.
ex affine_if_constant_gradient(const ex& e, const Symbols& x) {
  ex affine = 0;
  GiNaC::exmap origin;
  for (const auto& xi : x) {
    const ex d = simplify(GiNaC::normal(e.diff(xi)));
    if (!GiNaC::is_a<GiNaC::numeric>(d)) return e;
    affine += d * xi;
    origin[xi] = 0;
  }
  try {
    const ex offset = simplify(e.subs(origin));
    if (depends_on(offset, x)) return e;
    return affine + offset;
  } catch (const std::exception&) {  // psi(h) undefined at x = 0
    return e;
  }
}

// log(b^(2k)) -> 2k log(s b) where b has no zero on the domain box (proved) and s is its sign
// there (the box is connected): the integrator's log(y^2)/2 for log|y|, composed with h.
ex fold_log_of_even_power(const ex& e, const SampleBoxes& boxes) {
  return rewrite_bottom_up(e, [&](const ex& x) {
    if (!is_call(x, "log") || !GiNaC::is_a<GiNaC::power>(x.op(0)) ||
        !x.op(0).op(1).info(GiNaC::info_flags::even))
      return x;
    const ex b = x.op(0).op(0), k = x.op(0).op(1);
    if (zeros_in_box(b, boxes).kind != BoxZeros::never) return x;
    GiNaC::exmap centre;
    for (const auto& s : symbols_in(b)) {
      const Interval iv = boxes.box(s);
      centre[s] = (iv.lo + iv.hi) / 2;
    }
    GiNaC::numeric v;
    if (!evaluate_real(b, centre, 30, v) || v.is_zero()) return x;
    return ex(k * GiNaC::log(v.is_positive() ? b : -b));
  });
}

Model transformed_output(const Model& m, const ExVec& psi, const std::vector<GiNaC::symbol>& y) {
  Model t = m;
  const SampleBoxes boxes = m.sample_boxes();
  for (std::size_t i = 0; i < t.h.size(); ++i) {
    if (psi[i].is_equal(y[i])) continue;
    const ex composed = GiNaC::expand(psi[i].subs(y[i] == m.h[i]));
    t.h[i] = affine_if_constant_gradient(
        simplify(fold_log_exp(fold_log_of_even_power(composed, boxes))), m.states);
  }
  return t;
}

}  // namespace obsynth
