#include "analysis/canonical.hpp"

#include <fmt/format.h>

#include <functional>

#include "symbolic/expr_print.hpp"
#include "symbolic/integrate.hpp"
#include "symbolic/poly.hpp"
#include "symbolic/symbolic.hpp"

namespace obsynth {

using GiNaC::ex;
using GiNaC::numeric;

const char* completeness_name(Completeness c) {
  switch (c) {
    case Completeness::global:
      return "global";
    case Completeness::local:
      return "local";
    case Completeness::unknown:
      return "unknown";
  }
  return "unknown";
}

const char* availability_name(Availability a) {
  switch (a) {
    case Availability::symbolic:
      return "symbolic";
    case Availability::numeric:
      return "numeric";
    case Availability::none:
      return "none";
  }
  return "none";
}

namespace {

ZeroVerdict worst(ZeroVerdict a, ZeroVerdict b) {
  return static_cast<int>(a) > static_cast<int>(b) ? a : b;
}

ZeroVerdict vector_verdict(const ExVec& v, const SampleBoxes& boxes, const ZeroTestOptions& opt) {
  ZeroVerdict w = ZeroVerdict::proved;
  for (const auto& e : v) {
    w = worst(w, zero_test(e, boxes, opt));
    if (w == ZeroVerdict::nonzero) break;
  }
  return w;
}

bool bounded(const ex& e, const Symbols& x) {
  if (!depends_on(e, x)) return true;
  if (GiNaC::is_a<GiNaC::symbol>(e)) return false;
  if (GiNaC::is_a<GiNaC::function>(e)) {
    const std::string n = GiNaC::ex_to<GiNaC::function>(e).get_name();
    return n == "sin" || n == "cos" || n == "tanh" || n == "atan";
  }
  if (GiNaC::is_a<GiNaC::power>(e)) {
    const ex q = e.op(1);
    return GiNaC::is_a<numeric>(q) && GiNaC::ex_to<numeric>(q).is_pos_integer() &&
           bounded(e.op(0), x);
  }
  if (GiNaC::is_a<GiNaC::add>(e) || GiNaC::is_a<GiNaC::mul>(e)) {
    for (std::size_t i = 0; i < e.nops(); ++i)
      if (!bounded(e.op(i), x)) return false;
    return true;
  }
  return false;
}

// Base point: the origin when the domain box contains it, else the box centre.
ExVec choose_base_point(const Model& m) {
  ExVec x0;
  for (const auto& s : m.states) {
    const Interval b = m.box(s);
    if (b.lo <= 0 && b.hi >= 0)
      x0.push_back(0);
    else
      x0.push_back((b.lo + b.hi) / 2);
  }
  return x0;
}

GiNaC::exmap point_map(const Symbols& x, const ExVec& x0) {
  GiNaC::exmap mp;
  for (std::size_t i = 0; i < x.size(); ++i) mp[x[i]] = x0[i];
  return mp;
}

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

// Solve eq(xk) = 0 for xk when eq is linear in xk or in one invertible atom of xk.
std::optional<ex> solve_for(const ex& eq, const GiNaC::symbol& xk) {
  const ex e = GiNaC::expand(eq);
  const ex a = e.diff(xk);
  if (!a.is_zero() && !a.has(xk)) {
    const ex b = e.subs(xk == 0);
    return GiNaC::normal(-b / a);
  }
  // Linear in a single atom phi(xk)?
  std::vector<ex> atoms;
  std::function<void(const ex&)> find = [&](const ex& t) {
    if (GiNaC::is_a<GiNaC::function>(t) && t.has(xk)) {
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
  const ex wsol = GiNaC::normal(-ew.subs(w == 0) / aw);
  return invert_atom(atoms[0], xk, wsol);
}

// Values of vector fields and their Jacobians at one sample point, to screen brackets.
class BracketScreen {
 public:
  BracketScreen(const Model& m, const SampleBoxes& boxes, int digits)
      : digits_(digits), x_(m.states) {
    std::vector<GiNaC::symbol> syms(m.states);
    for (const auto& u : m.inputs) syms.push_back(u);
    for (const auto& q : m.free_params()) syms.push_back(q);
    point_ = sample_points(syms, boxes, 3, 0x5c4ee7).back();  // a random (not edge) point
  }
  void add(const ExVec& v, const ExMatrix& J) {
    Values val;
    val.ok = true;
    for (const auto& e : v) val.v.push_back(eval(e, val.ok));
    for (const auto& row : J) {
      std::vector<GiNaC::numeric> r;
      for (const auto& e : row) r.push_back(eval(e, val.ok));
      val.J.push_back(r);
    }
    fields_.push_back(std::move(val));
  }
  void add_values(std::vector<GiNaC::numeric> v, std::vector<std::vector<GiNaC::numeric>> J) {
    fields_.push_back({true, std::move(v), std::move(J)});
  }
  void add_unknown() { fields_.push_back({false, {}, {}}); }
  const GiNaC::exmap& point() const { return point_; }
  // [a, b] = Jb a - Ja b clearly nonzero at the point.
  bool nonzero(std::size_t a, std::size_t b) const {
    const Values& A = fields_[a];
    const Values& B = fields_[b];
    if (!A.ok || !B.ok) return false;
    const std::size_t n = A.v.size();
    const GiNaC::numeric tol = GiNaC::numeric(10).power(GiNaC::numeric(-(digits_ / 2)));
    for (std::size_t r = 0; r < n; ++r) {
      GiNaC::numeric acc = 0, scale = 1;
      for (std::size_t k = 0; k < n; ++k) {
        const GiNaC::numeric p = B.J[r][k] * A.v[k], q = A.J[r][k] * B.v[k];
        acc += p - q;
        scale = std::max(scale, std::max(GiNaC::abs(p), GiNaC::abs(q)));
      }
      if (GiNaC::abs(acc) > tol * scale) return true;
    }
    return false;
  }
  std::string point_text() const {
    std::vector<std::string> parts;
    for (const auto& s : x_) parts.push_back(s.get_name() + " = " + to_string(point_.at(s)));
    return fmt::format("{}", fmt::join(parts, ", "));
  }

 private:
  struct Values {
    bool ok = true;
    std::vector<GiNaC::numeric> v;
    std::vector<std::vector<GiNaC::numeric>> J;
  };
  GiNaC::numeric eval(const ex& e, bool& ok) const {
    GiNaC::numeric val;
    if (!evaluate_real(e, point_, digits_, val)) ok = false;
    return val;
  }
  int digits_;
  Symbols x_;
  GiNaC::exmap point_;
  std::vector<Values> fields_;
};

}  // namespace

ExVec frame_column_major(const CanonicalForm& cf) {
  ExVec flat;
  for (const auto& t : cf.frame) flat.insert(flat.end(), t.begin(), t.end());
  return flat;
}

namespace {

// C4 from how the Jacobian entries of a field grow: all constant (affine field) or all
// bounded (globally Lipschitz) proves completeness. Stops at the first unbounded entry.
Completeness classify_growth(const ExVec& v, const Symbols& x,
                             const std::function<Growth(std::size_t, std::size_t)>& entry,
                             std::string& reason) {
  auto text = [&](std::size_t i) {
    std::string s = to_string(v[i]);
    if (s.size() > 200) s = s.substr(0, 200) + "...";
    return s;
  };
  // Structural tests only (no normalisation): entries are already simplified.
  for (std::size_t i = 0; i < v.size(); ++i)
    if (has_denominator_in(v[i], x)) {
      reason = fmt::format("has a pole ({}): defined only locally", text(i));
      return Completeness::local;
    }
  bool affine = true;
  for (std::size_t i = 0; i < v.size(); ++i)
    for (std::size_t j = 0; j < x.size(); ++j) {
      const Growth g = entry(i, j);
      if (g == Growth::unbounded) {
        reason = fmt::format("component {} grows faster than linearly; completeness not decided",
                             text(i));
        return Completeness::unknown;
      }
      if (g == Growth::bounded) affine = false;
    }
  reason =
      affine
          ? "affine in x, hence complete"
          : "Jacobian bounded (sin, cos, tanh, atan of x only), globally Lipschitz, hence complete";
  return Completeness::global;
}

}  // namespace

Completeness classify_completeness(const ExVec& v, const Symbols& x, std::string& reason) {
  return classify_growth(
      v, x,
      [&](std::size_t i, std::size_t j) {
        const ex d = v[i].diff(x[j]);
        if (!depends_on(d, x)) return Growth::constant;
        return bounded(d, x) ? Growth::bounded : Growth::unbounded;
      },
      reason);
}

std::optional<ex> express_in_output(const ex& e, const ex& h, const Symbols& x,
                                    const GiNaC::symbol& y, const ExVec& base_point,
                                    const SampleBoxes& boxes) {
  // Choose a state in which h is linear with a coefficient free of that state.
  std::optional<std::size_t> k;
  for (std::size_t i = 0; i < x.size(); ++i)
    if (h.is_equal(x[i])) k = i;
  ex solution;
  if (k) {
    solution = y;
  } else {
    for (std::size_t i = 0; i < x.size() && !k; ++i) {
      const auto s = solve_for(h - y, x[i]);
      if (s) {
        k = i;
        solution = *s;
      }
    }
  }
  if (!k) return std::nullopt;
  ex r = simplify(e.subs(x[*k] == solution));
  Symbols others;
  for (std::size_t i = 0; i < x.size(); ++i)
    if (i != *k && r.has(x[i])) others.push_back(x[i]);
  if (others.empty()) return r;
  // Remaining dependence must vanish identically (e.g. sin^2 + cos^2 left by normal()).
  for (const auto& s : others)
    if (zero_test(r.diff(s), boxes) == ZeroVerdict::nonzero) return std::nullopt;
  GiNaC::exmap at;
  for (std::size_t i = 0; i < x.size(); ++i)
    if (i != *k) at[x[i]] = base_point[i];
  return simplify(r.subs(at));
}

std::optional<ExVec> invert_map(const ExVec& T, const Symbols& x,
                                const std::vector<GiNaC::symbol>& z, const SampleBoxes& boxes) {
  const std::size_t n = x.size();
  std::vector<ex> eqs;
  for (std::size_t i = 0; i < n; ++i) eqs.push_back(T[i] - z[i]);
  std::vector<bool> used(n, false), solved(n, false);
  std::vector<ex> sol(n);
  std::vector<std::size_t> order;
  for (std::size_t step = 0; step < n; ++step) {
    // Prefer the equation with the fewest unsolved states (triangular structure first).
    std::optional<std::pair<std::size_t, std::size_t>> pick;
    std::size_t best = n + 1;
    ex best_sol;
    for (std::size_t i = 0; i < n; ++i) {
      if (used[i]) continue;
      std::size_t count = 0;
      for (std::size_t k = 0; k < n; ++k)
        if (!solved[k] && eqs[i].has(x[k])) ++count;
      if (count == 0 || count >= best) continue;
      for (std::size_t k = 0; k < n; ++k) {
        if (solved[k] || !eqs[i].has(x[k])) continue;
        auto s = solve_for(eqs[i], x[k]);
        if (s) {
          pick = {i, k};
          best = count;
          best_sol = *s;
          break;
        }
      }
    }
    if (!pick) return std::nullopt;
    const auto [i, k] = *pick;
    used[i] = solved[k] = true;
    sol[k] = best_sol;
    order.push_back(k);
    for (std::size_t q = 0; q < n; ++q)
      if (!used[q]) eqs[q] = simplify(eqs[q].subs(x[k] == best_sol));
  }
  // Back-substitute: later solutions are free of earlier-eliminated states.
  for (std::size_t a = order.size(); a-- > 0;) {
    const std::size_t k = order[a];
    for (std::size_t b = 0; b < a; ++b) {
      const std::size_t q = order[b];
      sol[q] = sol[q].subs(x[k] == sol[k]);
    }
  }
  ExVec out;
  for (std::size_t k = 0; k < n; ++k) {
    const ex s = simplify(sol[k]);
    if (depends_on(s, x)) return std::nullopt;
    out.push_back(s);
  }
  (void)boxes;
  return out;
}

CanonicalForm analyse_canonical(const Model& m, const Observability& ob, Budget& budget,
                                const CanonicalOptions& opt, CanonicalForm* progress) {
  CanonicalForm local;
  CanonicalForm& cf = progress ? *progress : local;
  const std::size_t n = m.n();
  const Symbols& x = m.states;
  for (std::size_t i = 0; i < n; ++i) cf.z.push_back(GiNaC::symbol(fmt::format("z{}", i + 1)));
  if (m.p() != 1) {
    cf.not_applicable = fmt::format(
        "the canonical-form stages (r, frame, brackets, T, l) are single-output for now; this "
        "model has {} outputs",
        m.p());
    return cf;
  }
  if (ob.generic_rank < n) {
    cf.not_applicable =
        fmt::format("C1 fails: the generic observability rank is {} < n = {}", ob.generic_rank, n);
    return cf;
  }
  cf.applicable = true;
  const SampleBoxes boxes = SampleBoxes::from_model(m);

  // The frame and g, with their Jacobians: in the polynomial ring when f, g and r live in it
  // (brackets of polynomial fields are polynomial), else as GiNaC expressions.
  std::optional<PolyRing> ring;
  std::vector<std::vector<Poly>> field_polys;             // tau_1..tau_n, g
  std::vector<std::vector<std::vector<Poly>>> jac_polys;  // their Jacobians
  auto poly_jacobian = [&](const std::vector<Poly>& v) {
    std::vector<std::vector<Poly>> J(v.size());
    for (std::size_t i = 0; i < v.size(); ++i)
      for (std::size_t j = 0; j < n; ++j) J[i].push_back(ring->derivative(v[i], j));
    return J;
  };
  {
    StageScope stage(budget, "frame");
    // r = adj(O) e_n / det O: the cofactors of O's last row.
    for (std::size_t i = 0; i < n; ++i) cf.r.push_back(simplify(ob.last_row_cofactors[i] / ob.det));
    ExVec all(m.f);
    all.insert(all.end(), m.g.begin(), m.g.end());
    all.insert(all.end(), cf.r.begin(), cf.r.end());
    ring = PolyRing::for_expressions(all, x);
    try {
      if (ring) {
        // tau_{k+1} = [-f, tau_k] = J_f tau_k - J_tau_k f
        std::vector<Poly> f, tau;
        for (const auto& e : m.f) f.push_back(*ring->from_ex(e));
        for (const auto& e : cf.r) tau.push_back(*ring->from_ex(e));
        const auto Jf = poly_jacobian(f);
        for (std::size_t k = 0; k < n; ++k) {
          if (k > 0) {
            const auto& prev = field_polys.back();
            const auto& Jprev = jac_polys.back();
            tau.assign(n, Poly{});
            for (std::size_t i = 0; i < n; ++i) {
              tau[i] = PolyRing::dot(Jf[i], prev);
              PolyRing::subtract_from(tau[i], PolyRing::dot(Jprev[i], f));
            }
          }
          std::size_t estimate = 0;
          for (const auto& p : tau) estimate = std::max(estimate, p.node_estimate());
          budget.check(estimate);
          field_polys.push_back(tau);
          jac_polys.push_back(poly_jacobian(tau));
          ExVec t;
          std::size_t sz = 0;
          for (const auto& p : tau) {
            t.push_back(ring->to_ex(p));
            sz = std::max(sz, expression_size(t.back()));
          }
          cf.frame.push_back(std::move(t));
          budget.check(sz);
        }
      }
    } catch (const PolyOverflow&) {
      ring.reset();
      cf.frame.clear();
      field_polys.clear();
      jac_polys.clear();
    }
    if (!ring) {
      // tau_1 = r, tau_{k+1} = [-f, tau_k] = J_f tau_k - J_tau_k f
      ExVec minus_f;
      for (const auto& e : m.f) minus_f.push_back(-e);
      const ExMatrix Jmf = jacobian(minus_f, x);
      cf.frame.push_back(cf.r);
      for (std::size_t k = 1; k < n; ++k) {
        cf.frame.push_back(
            lie_bracket(minus_f, Jmf, cf.frame.back(), jacobian(cf.frame.back(), x)));
        std::size_t sz = 0;
        for (const auto& e : cf.frame.back()) sz = std::max(sz, expression_size(e));
        budget.check(sz);
      }
    }
  }
  {
    StageScope stage(budget, "conditions");
    // Numeric screen: every bracket evaluated at one point of the domain from the values of
    // tau_k and their Jacobians. A clearly nonzero value proves failure without the symbolic
    // expansion (which dominates on large models); vanishing brackets get the full test.
    BracketScreen screen(m, boxes, opt.zero.digits);
    std::vector<ExMatrix> J;  // GiNaC path only
    if (ring) {
      std::vector<Poly> g;
      for (const auto& e : m.g) g.push_back(*ring->from_ex(e));
      jac_polys.push_back(poly_jacobian(g));
      field_polys.push_back(std::move(g));
      const auto values = ring->values_at(screen.point(), opt.zero.digits);
      DigitsGuard guard(opt.zero.digits);
      for (std::size_t k = 0; k <= n; ++k) {
        if (!values) {
          screen.add_unknown();
          continue;
        }
        std::vector<numeric> v;
        std::vector<std::vector<numeric>> Jv;
        for (std::size_t i = 0; i < n; ++i) {
          v.push_back(PolyRing::evaluate(field_polys[k][i], *values));
          Jv.emplace_back();
          for (std::size_t j = 0; j < n; ++j)
            Jv.back().push_back(PolyRing::evaluate(jac_polys[k][i][j], *values));
        }
        screen.add_values(std::move(v), std::move(Jv));
      }
    } else {
      for (const auto& t : cf.frame) J.push_back(jacobian(t, x));
      J.push_back(jacobian(m.g, x));
      for (std::size_t k = 0; k < n; ++k) screen.add(cf.frame[k], J[k]);
      screen.add(m.g, J[n]);
    }
    auto bracket = [&](std::size_t a, std::size_t b) {
      const ExVec& va = a < n ? cf.frame[a] : m.g;
      const ExVec& vb = b < n ? cf.frame[b] : m.g;
      if (!ring) return lie_bracket(va, J[a], vb, J[b]);
      ExVec out;
      for (std::size_t i = 0; i < n; ++i) {
        Poly r = PolyRing::dot(jac_polys[b][i], field_polys[a]);
        PolyRing::subtract_from(r, PolyRing::dot(jac_polys[a][i], field_polys[b]));
        out.push_back(ring->to_ex(r));
      }
      return out;
    };
    // Node counts of tau_1..tau_n and g, each counted once (pairs reuse them).
    std::vector<std::size_t> field_size;
    for (std::size_t k = 0; k <= n; ++k) {
      std::size_t size = 0;
      for (const auto& e : k < n ? cf.frame[k] : m.g) size += expression_size(e);
      field_size.push_back(size);
    }
    auto check_pair = [&](std::size_t a, std::size_t b, BracketCheck& out) {
      if (screen.nonzero(a, b)) {
        out.verdict = ZeroVerdict::nonzero;
        // The residual itself, unless its symbolic form would be unreasonably large.
        const std::size_t size = field_size[a] + field_size[b];
        if (size <= 4000)
          out.residual = bracket(a, b);
        else
          out.residual_note =
              fmt::format("residual not printed (operands have {} nodes); nonzero at {}", size,
                          screen.point_text());
        return;
      }
      out.residual = bracket(a, b);
      out.verdict = vector_verdict(out.residual, boxes, opt.zero);
    };
    bool ok = true;
    for (std::size_t i = 0; i < n; ++i)
      for (std::size_t j = i + 1; j < n; ++j) {
        BracketCheck b;
        b.i = i + 1;
        b.j = j + 1;
        check_pair(i, j, b);
        ok &= b.holds();
        cf.drift.push_back(std::move(b));
        budget.check();
      }
    for (std::size_t j = 0; j + 1 < n; ++j) {
      BracketCheck b;
      b.i = 0;
      b.j = j + 1;
      check_pair(n, j, b);
      ok &= b.holds();
      cf.input.push_back(std::move(b));
      budget.check();
    }
    cf.linearizable = ok;
    // C4: every tau_k complete.
    cf.complete = Completeness::global;
    std::vector<std::string> reasons;
    for (std::size_t k = 0; k < n; ++k) {
      std::string why;
      const Completeness c =
          ring ? classify_growth(
                     cf.frame[k], x,
                     [&](std::size_t i, std::size_t j) { return ring->growth(jac_polys[k][i][j]); },
                     why)
               : classify_completeness(cf.frame[k], x, why);
      reasons.push_back(fmt::format("tau_{} {}", k + 1, why));
      if (c == Completeness::local ||
          (c == Completeness::unknown && cf.complete == Completeness::global))
        cf.complete = c;
    }
    cf.complete_reason = fmt::format("{}", fmt::join(reasons, "; "));
  }
  if (!cf.linearizable) {
    cf.T_note = cf.T_inverse_note = cf.l_note =
        "not computed: the bracket conditions fail, no observer canonical form exists";
    return cf;
  }

  StageScope stage(budget, "diffeomorphism");
  cf.base_point = choose_base_point(m);
  const GiNaC::exmap at_x0 = point_map(x, cf.base_point);
  const ex& h = m.h[0];
  const ex y0 = simplify(h.subs(at_x0));
  const ExVec& tau_n = cf.frame[n - 1];
  // z_n = h - h(x0); z_{i-1} = L_f z_i - l_i(y) with l_i'(y) = L_{tau_n} L_f z_i (a function
  // of y alone when C2 holds), the constant fixing T_{i-1}(x0) = 0.
  ExVec T(n);
  T[n - 1] = simplify(h - y0);
  bool closed = true;
  for (std::size_t i = n - 1; i >= 1 && closed; --i) {
    const ex LfTi = lie_derivative(T[i], m.f, x);
    const ex a_x = lie_derivative(LfTi, tau_n, x);
    const auto a_y = express_in_output(a_x, h, x, cf.y, cf.base_point, boxes);
    if (!a_y) {
      closed = false;
      cf.T_note = fmt::format("L_tau_n L_f T_{} = {} could not be written as a function of y",
                              i + 1, to_string(a_x));
      break;
    }
    const auto A = antiderivative(*a_y, cf.y);
    if (!A) {
      closed = false;
      cf.T_note = fmt::format("no closed-form antiderivative in y of {}", to_string(*a_y));
      break;
    }
    const ex integral = A->subs(cf.y == h) - A->subs(cf.y == y0);
    const ex c = simplify(LfTi.subs(at_x0));
    T[i - 1] = simplify(LfTi - integral - c);
    budget.check(expression_size(T[i - 1]));
  }
  if (!closed) {
    cf.T_kind = Availability::numeric;
    cf.T_note += "; T is to be evaluated numerically (quadrature of the closed 1-form [tau]^-1 dx)";
    cf.T_inverse_kind = Availability::numeric;
    cf.T_inverse_note = "runtime Newton solve with [tau] as inverse Jacobian";
    cf.l_note = "needs T in closed form";
    return cf;
  }
  // Verify dT/dx [tau] = I by substitution.
  ZeroVerdict v = ZeroVerdict::proved;
  for (std::size_t i = 0; i < n && v != ZeroVerdict::nonzero; ++i) {
    const ExVec dTi = gradient(T[i], x);
    for (std::size_t j = 0; j < n; ++j) {
      ex acc = 0;
      for (std::size_t k = 0; k < n; ++k) acc += dTi[k] * cf.frame[j][k];
      v = worst(v, zero_test(simplify(acc - (i == j ? 1 : 0)), boxes, opt.zero));
    }
  }
  cf.T_verdict = v;
  if (v == ZeroVerdict::nonzero) {
    OBSYNTH_ASSERT(false, "constructed T does not satisfy dT/dx [tau] = I");
  }
  cf.T = T;
  cf.T_kind = Availability::symbolic;
  cf.T_note = fmt::format("dT/dx [tau] = I {}",
                          v == ZeroVerdict::proved ? "proved" : "verified numerically");

  // l_i = L_{f+g} T_i - T_{i-1}, as a function of (u, y).
  {
    const ExVec F = m.field();
    ExVec l;
    ZeroVerdict lv = ZeroVerdict::proved;
    for (std::size_t i = 0; i < n; ++i) {
      const ex li_x = simplify(lie_derivative(T[i], F, x) - (i > 0 ? T[i - 1] : ex(0)));
      const auto li = express_in_output(li_x, h, x, cf.y, cf.base_point, boxes);
      if (!li) {
        lv = ZeroVerdict::nonzero;
        cf.l_note = fmt::format("l_{} = {} is not a function of (u, y)", i + 1, to_string(li_x));
        break;
      }
      // Independent check: l_i(u, h(x)) equals the x-expression.
      lv = worst(lv, zero_test(simplify(li->subs(cf.y == h) - li_x), boxes, opt.zero));
      l.push_back(*li);
    }
    cf.l_verdict = lv;
    if (lv != ZeroVerdict::nonzero) {
      cf.l = l;
      cf.l_kind = Availability::symbolic;
      cf.l_note = "l(u, h(x)) = L_{f+g} T - A T verified by substitution";
    }
  }
  // T^-1 by elimination, verified by T^-1(T(x)) = x.
  {
    const auto inv = invert_map(T, x, cf.z, boxes);
    if (inv) {
      GiNaC::exmap zt;
      for (std::size_t i = 0; i < n; ++i) zt[cf.z[i]] = T[i];
      ZeroVerdict iv = ZeroVerdict::proved;
      for (std::size_t k = 0; k < n; ++k)
        iv = worst(iv, zero_test(simplify((*inv)[k].subs(zt) - x[k]), boxes, opt.zero));
      cf.T_inverse_verdict = iv;
      if (iv != ZeroVerdict::nonzero) {
        cf.T_inverse = *inv;
        cf.T_inverse_kind = Availability::symbolic;
        cf.T_inverse_note = "T^-1(T(x)) = x verified by substitution";
      } else {
        cf.T_inverse_note = "elimination gave a branch that does not invert T on the domain";
      }
    } else {
      cf.T_inverse_note = "T is not triangular in a solvable way";
    }
    if (cf.T_inverse_kind != Availability::symbolic) {
      cf.T_inverse_kind = Availability::numeric;
      cf.T_inverse_note += "; runtime Newton solve with [tau] as inverse Jacobian";
    }
  }
  return cf;
}

}  // namespace obsynth
