#include "analysis/conditions.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <functional>
#include <map>
#include <memory>

#include "analysis/flint_products.hpp"
#include "symbolic/expr_print.hpp"
#include "symbolic/lie.hpp"
#include "symbolic/symbolic.hpp"
#include "symbolic/zero_test.hpp"

namespace obsynth {

using GiNaC::ex;
using GiNaC::numeric;

namespace {

ZeroVerdict worst(ZeroVerdict a, ZeroVerdict b) {
  return static_cast<int>(a) > static_cast<int>(b) ? a : b;
}

// The worst verdict over the components, with the evidence: the points where every numeric
// component vanished (the fewest), or the first clearly nonzero component's witness.
ZeroTestResult vector_verdict(const ExVec& v, const SampleBoxes& boxes,
                              const ZeroTestOptions& opt) {
  ZeroTestResult w;
  w.verdict = ZeroVerdict::proved;
  for (const auto& e : v) {
    ZeroTestResult r = zero_test_detailed(e, boxes, opt);
    if (r.verdict == ZeroVerdict::nonzero) return r;
    if (r.verdict == ZeroVerdict::numeric)
      w.zero_points = w.verdict == ZeroVerdict::numeric ? std::min(w.zero_points, r.zero_points)
                                                        : r.zero_points;
    w.verdict = worst(w.verdict, r.verdict);
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

namespace {

// Every bracket value at one sample point, from the fields and their Jacobians.
BracketScreen make_screen(const Model& m, FrameRing& fr, const SampleBoxes& boxes,
                          const CanonicalForm& cf, const CanonicalOptions& opt,
                          std::vector<ExMatrix>& J) {
  const std::size_t n = m.n();
  BracketScreen screen(m, boxes, opt.zero.digits);
  if (!fr.ring) {
    for (const auto& t : cf.frame) J.push_back(jacobian(t, m.states));
    J.push_back(jacobian(m.g, m.states));
    for (std::size_t k = 0; k < n; ++k) screen.add(cf.frame[k], J[k]);
    screen.add(m.g, J[n]);
    return screen;
  }
  std::vector<Poly> g;
  for (const auto& e : m.g) g.push_back(*fr.ring->from_ex(e));
  fr.add_field(std::move(g));
  const auto values = fr.ring->values_at(screen.point(), opt.zero.digits);
  DigitsGuard guard(opt.zero.digits);
  for (std::size_t k = 0; k <= n; ++k) {
    if (!values) {
      screen.add_unknown();
      continue;
    }
    std::vector<numeric> v;
    std::vector<std::vector<numeric>> Jv;
    for (std::size_t i = 0; i < n; ++i) {
      v.push_back(PolyRing::evaluate(fr.fields[k][i], *values));
      Jv.emplace_back();
      for (std::size_t j = 0; j < n; ++j)
        Jv.back().push_back(PolyRing::evaluate(fr.jacobians[k][i][j], *values));
    }
    screen.add_values(std::move(v), std::move(Jv));
  }
  return screen;
}

// C4: every tau_k complete.
void check_completeness(const Model& m, const FrameRing& fr, CanonicalForm& cf) {
  cf.complete = Completeness::global;
  std::vector<std::string> reasons;
  for (std::size_t k = 0; k < m.n(); ++k) {
    std::string why;
    const Completeness c = fr.ring ? classify_growth(
                                         cf.frame[k], m.states,
                                         [&](std::size_t i, std::size_t j) {
                                           return fr.ring->growth(fr.jacobians[k][i][j]);
                                         },
                                         why)
                                   : classify_completeness(cf.frame[k], m.states, why);
    reasons.push_back(fmt::format("{} {}", cf.tau_name(k), why));
    if (c == Completeness::local ||
        (c == Completeness::unknown && cf.complete == Completeness::global))
      cf.complete = c;
  }
  cf.complete_reason = fmt::format("{}", fmt::join(reasons, "; "));
}

}  // namespace

namespace {

// Brackets of large ring fields decided by exact evaluation at random integer points, with
// every ring variable (states, symbols and atoms alike) drawn independently and uniformly from
// 2^32 integers: a nonzero polynomial of degree d vanishes at such a point with probability
// <= d / 2^32 (Schwartz-Zippel), so three points bound the error by (d / 2^32)^3. Integers
// keep the exact arithmetic free of gcds. A bracket that is zero only modulo an identity
// between atoms (sin^2 + cos^2 = 1) does not vanish here and takes the symbolic path.
class ExactScreen {
 public:
  static constexpr int kPoints = 3;
  explicit ExactScreen(const FrameRing& fr) : fr_(fr), values_(kPoints) {
    std::uint64_t state = 0x9e3779b97f4a7c15ULL;
    for (auto& point : values_)
      for (std::size_t v = 0; v < kMaxPolyVariables; ++v) {
        state = state * 6364136223846793005ULL + 1442695040888963407ULL;
        point.push_back(numeric(static_cast<long>(state >> 32) - (1L << 31)));
      }
  }
  // [a, b] = J_b a - J_a b vanishes at every point.
  bool zero(std::size_t a, std::size_t b) {
    for (int k = 0; k < kPoints; ++k) {
      const Values& A = at(a, k);
      const Values& B = at(b, k);
      for (std::size_t i = 0; i < A.v.size(); ++i) {
        numeric acc = 0;
        for (std::size_t j = 0; j < A.v.size(); ++j) acc += B.J[i][j] * A.v[j] - A.J[i][j] * B.v[j];
        if (!acc.is_zero()) return false;
      }
    }
    return true;
  }

 private:
  struct Values {
    std::vector<numeric> v;
    std::vector<std::vector<numeric>> J;
  };
  const Values& at(std::size_t field, int k) {
    auto& slot = cache_[{field, k}];
    if (slot.v.empty()) {
      for (const auto& p : fr_.fields[field]) slot.v.push_back(PolyRing::evaluate(p, values_[k]));
      for (const auto& row : fr_.jacobians[field]) {
        slot.J.emplace_back();
        for (const auto& p : row) slot.J.back().push_back(PolyRing::evaluate(p, values_[k]));
      }
    }
    return slot;
  }
  const FrameRing& fr_;
  std::vector<std::vector<numeric>> values_;
  std::map<std::pair<std::size_t, int>, Values> cache_;
};

// Operands above this many GiNaC nodes are decided by the exact screen when it can (their
// symbolic bracket costs products of dense polynomials) and their failing residuals are not
// printed.
constexpr std::size_t kLargeOperands = 4000;

// One bracket check: [a, b] with a, b indexing tau_1..tau_n, g (index n).
class BracketChecker {
 public:
  BracketChecker(const Model& m, FrameRing& fr, const CanonicalForm& cf, const SampleBoxes& boxes,
                 const CanonicalOptions& opt)
      : m_(m),
        fr_(fr),
        cf_(cf),
        boxes_(boxes),
        opt_(opt),
        screen_(make_screen(m, fr, boxes, cf, opt, J_)),
        exact_(fr) {
    for (std::size_t k = 0; k <= m.n(); ++k) {
      std::size_t size = 0;
      for (const auto& e : k < m.n() ? cf.frame[k] : m.g) size += expression_size(e);
      field_size_.push_back(size);
    }
  }

  BracketCheck check(std::size_t a, std::size_t b) {
    BracketCheck out;
    const std::size_t size = field_size_[a] + field_size_[b];
    if (screen_.nonzero(a, b)) {
      out.verdict = ZeroVerdict::nonzero;
      out.witness = screen_.point();
      // The residual itself, unless its symbolic form would be unreasonably large.
      if (size <= kLargeOperands)
        out.residual = bracket(a, b);
      else
        out.residual_note =
            fmt::format("residual not printed (operands have {} nodes); nonzero at {}", size,
                        screen_.point_text());
      return out;
    }
    if (fr_.ring && size > kLargeOperands && exact_.zero(a, b)) {
      out.verdict = ZeroVerdict::numeric;
      out.zero_points = ExactScreen::kPoints;
      out.residual_note = fmt::format(
          "zero at {} random integer points in exact arithmetic (operands have {} nodes; "
          "Schwartz-Zippel: error probability below (degree / 2^32)^{})",
          ExactScreen::kPoints, size, ExactScreen::kPoints);
      return out;
    }
    out.residual = bracket(a, b);
    ZeroTestResult r = vector_verdict(out.residual, boxes_, opt_.zero);
    out.verdict = r.verdict;
    out.zero_points = r.zero_points;
    out.witness = std::move(r.witness);
    return out;
  }

 private:
  ExVec bracket(std::size_t a, std::size_t b) {
    const std::size_t n = m_.n();
    const ExVec& va = a < n ? cf_.frame[a] : m_.g;
    const ExVec& vb = b < n ? cf_.frame[b] : m_.g;
    if (!fr_.ring) return lie_bracket(va, J_[a], vb, J_[b]);
    const Handles& A = handles(a);
    const Handles& B = handles(b);
    ExVec out;
    for (std::size_t i = 0; i < n; ++i)
      out.push_back(fr_.ring->to_ex(flint_->dot_difference(B.J[i], A.v, A.J[i], B.v)));
    return out;
  }

  // The ring fields converted to FLINT once, on first use.
  struct Handles {
    std::vector<FlintProducts::Handle> v;
    std::vector<std::vector<FlintProducts::Handle>> J;
  };
  const Handles& handles(std::size_t field) {
    if (!flint_) flint_ = std::make_unique<FlintProducts>(fr_.ring->variables());
    auto& h = handles_[field];
    if (h.v.empty()) {
      for (const auto& p : fr_.fields[field]) h.v.push_back(flint_->add(p));
      for (const auto& row : fr_.jacobians[field]) {
        h.J.emplace_back();
        for (const auto& p : row) h.J.back().push_back(flint_->add(p));
      }
    }
    return h;
  }
  std::unique_ptr<FlintProducts> flint_;
  std::map<std::size_t, Handles> handles_;

  const Model& m_;
  FrameRing& fr_;
  const CanonicalForm& cf_;
  const SampleBoxes& boxes_;
  const CanonicalOptions& opt_;
  std::vector<ExMatrix> J_;  // GiNaC path only
  BracketScreen screen_;
  ExactScreen exact_;
  std::vector<std::size_t> field_size_;  // nodes of tau_1..tau_n and g
};

// C5 <dh_l, tau_j> = delta_{l, output of j} [j a block end]: the outputs read the block ends.
// Implied by the dual frame for one output or equal indices (O r_i = e_(i, k_i - 1) gives
// <dL_f^m h_l, r_i> = 0 for m < k_i = k_l); checked otherwise.
bool check_outputs(const Model& m, const SampleBoxes& boxes, const CanonicalOptions& opt,
                   CanonicalForm& cf) {
  const auto& k = cf.blocks;
  if (std::all_of(k.begin(), k.end(), [&](std::size_t b) { return b == k.front(); })) return true;
  bool ok = true;
  for (std::size_t l = 0; l < m.p(); ++l) {
    const ExVec dh = gradient(m.h[l], m.states);
    for (std::size_t j = 0; j < m.n(); ++j) {
      ex acc = j == cf.block_end(l) ? ex(-1) : ex(0);
      for (std::size_t c = 0; c < m.n(); ++c) acc += dh[c] * cf.frame[j][c];
      BracketCheck b;
      b.i = l + 1;
      b.j = j + 1;
      b.residual = {simplify(acc)};
      ZeroTestResult r = vector_verdict(b.residual, boxes, opt.zero);
      b.verdict = r.verdict;
      b.zero_points = r.zero_points;
      b.witness = std::move(r.witness);
      ok &= b.holds();
      cf.output.push_back(std::move(b));
    }
  }
  return ok;
}

}  // namespace

void check_conditions(const Model& m, FrameRing& fr, Budget& budget, const CanonicalOptions& opt,
                      CanonicalForm& cf) {
  StageScope stage(budget, "conditions");
  const std::size_t n = m.n();
  const SampleBoxes boxes = m.sample_boxes();
  // Numeric screen first: every bracket evaluated at one point of the domain from the values
  // of tau_k and their Jacobians. A clearly nonzero value proves failure without the symbolic
  // expansion (which dominates on large models); vanishing brackets get the full test.
  BracketChecker checker(m, fr, cf, boxes, opt);
  bool ok = true;
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = i + 1; j < n; ++j) {
      BracketCheck b = checker.check(i, j);
      b.i = i + 1;
      b.j = j + 1;
      ok &= b.holds();
      cf.drift.push_back(std::move(b));
      budget.check();
    }
  for (std::size_t j = 0; j < n; ++j) {
    if (cf.is_block_end(j)) continue;
    BracketCheck b = checker.check(n, j);
    b.i = 0;
    b.j = j + 1;
    ok &= b.holds();
    cf.input.push_back(std::move(b));
    budget.check();
  }
  ok &= check_outputs(m, boxes, opt, cf);
  cf.linearizable = ok;
  check_completeness(m, fr, cf);
}

bool conditions_proved(const CanonicalForm& cf) {
  auto proved = [](const BracketCheck& b) { return b.verdict == ZeroVerdict::proved; };
  return std::all_of(cf.drift.begin(), cf.drift.end(), proved) &&
         std::all_of(cf.input.begin(), cf.input.end(), proved) &&
         std::all_of(cf.output.begin(), cf.output.end(), proved);
}

std::string drift_condition_name(const CanonicalForm& cf, const BracketCheck& b) {
  return fmt::format("[{}, {}] = 0", cf.tau_name(b.i - 1), cf.tau_name(b.j - 1));
}

std::string input_condition_name(const CanonicalForm& cf, const BracketCheck& b) {
  return fmt::format("[g, {}] = 0", cf.tau_name(b.j - 1));
}

std::string output_condition_name(const CanonicalForm& cf, const BracketCheck& b) {
  return fmt::format("<dh_{}, {}> = {}", b.i, cf.tau_name(b.j - 1),
                     b.j - 1 == cf.block_end(b.i - 1) ? 1 : 0);
}

std::vector<std::string> unproven_steps(const CanonicalForm& cf) {
  std::vector<std::string> out;
  auto unproven = [&](const std::vector<BracketCheck>& list, auto name) {
    for (const auto& b : list)
      if (b.verdict == ZeroVerdict::numeric)
        out.push_back(
            fmt::format("{} (numerically zero at {} points)", name(cf, b), b.zero_points));
  };
  unproven(cf.drift, drift_condition_name);
  unproven(cf.input, input_condition_name);
  unproven(cf.output, output_condition_name);
  auto map_step = [&](Availability kind, ZeroVerdict v, const char* what) {
    if (kind == Availability::symbolic && v == ZeroVerdict::numeric)
      out.push_back(fmt::format("{} (numerically only)", what));
  };
  map_step(cf.T_kind, cf.T_verdict, "dT/dx [tau] = I");
  map_step(cf.T_inverse_kind, cf.T_inverse_verdict, "T^-1 steps solve T(x) = z");
  map_step(cf.l_kind, cf.l_verdict, "l(u, y) free of x");
  return out;
}

std::string bracket_verdict_text(const BracketCheck& b) {
  switch (b.verdict) {
    case ZeroVerdict::proved:
      return "holds (proved)";
    case ZeroVerdict::numeric:
      return fmt::format("unproven (numerically zero at {} points)", b.zero_points);
    case ZeroVerdict::nonzero:
      break;
  }
  return "FAILS (nonzero)";
}

std::string witness_text(const Model& m, const BracketCheck& b) {
  std::vector<std::string> parts;
  for (const auto& s : m.all_symbols()) {
    const auto it = b.witness.find(s);
    if (it == b.witness.end()) continue;
    DigitsGuard guard(17);
    const double v = GiNaC::ex_to<numeric>(GiNaC::evalf(it->second)).to_double();
    parts.push_back(fmt::format("{} = {:.6g}", s.get_name(), v));
  }
  return fmt::format("{}", fmt::join(parts, ", "));
}

}  // namespace obsynth
