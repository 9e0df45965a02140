#include "certify/definedness.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <deque>
#include <limits>
#include <optional>

#include "certify/enclosure.hpp"
#include "certify/tape.hpp"
#include "symbolic/expr_print.hpp"

namespace obsynth::certify {

using detail::BallVec;
using detail::Tape;
using GiNaC::ex;

namespace {

// ----- the conditions an expression's operations put on their arguments -----------------

enum class Need { nonzero, nonnegative, positive };

struct Condition {
  ex arg;
  Need need;
  std::string what;  // "a denominator", "sqrt's argument", ...
};

void add_condition(std::vector<Condition>& out, const ex& arg, Need need, std::string what) {
  if (GiNaC::is_a<GiNaC::numeric>(arg)) return;  // constants were checked by the parser
  for (const auto& c : out)
    if (c.need == need && c.arg.is_equal(arg)) return;
  out.push_back({arg, need, std::move(what)});
}

// A divisor's factors each give a condition (the finding then names the factor that vanishes:
// x1 + 1 in 1/(x1 x2 - x1 + x2 - 1)), when the divisor is a small polynomial.
void add_divisor(std::vector<Condition>& out, const ex& divisor) {
  ex factored = divisor;
  // Small divisors only: GiNaC's multivariate factorisation has no budget of its own.
  constexpr std::size_t kMaxTermsToFactor = 24;
  if (divisor.info(GiNaC::info_flags::rational_polynomial) &&
      GiNaC::expand(divisor).nops() <= kMaxTermsToFactor)
    factored = GiNaC::factor(divisor);
  if (!GiNaC::is_a<GiNaC::mul>(factored)) {
    add_condition(out, divisor, Need::nonzero, "a denominator");
    return;
  }
  for (std::size_t i = 0; i < factored.nops(); ++i) {
    ex f = factored.op(i);
    if (GiNaC::is_a<GiNaC::power>(f) && f.op(1).info(GiNaC::info_flags::posint)) f = f.op(0);
    add_condition(out, f, Need::nonzero, "a factor of a denominator");
  }
}

void power_conditions(const GiNaC::power& p, std::vector<Condition>& out) {
  const ex base = p.op(0), exponent = p.op(1);
  if (!GiNaC::is_a<GiNaC::numeric>(exponent)) {
    add_condition(out, base, Need::positive, "the base of a symbolic power");
    return;
  }
  const auto e = GiNaC::ex_to<GiNaC::numeric>(exponent);
  if (e.is_integer()) {
    if (e.is_negative()) add_divisor(out, base);
    return;
  }
  const bool is_sqrt = e == GiNaC::numeric(1, 2) || e == GiNaC::numeric(-1, 2);
  const std::string what = is_sqrt ? "sqrt's argument" : "the base of a fractional power";
  add_condition(out, base, e.is_negative() ? Need::positive : Need::nonnegative, what);
}

void function_conditions(const GiNaC::function& f, std::vector<Condition>& out) {
  const std::string name = f.get_name();
  const ex a = f.op(0);
  if (name == "log")
    add_condition(out, a, Need::positive, "log's argument");
  else if (name == "tan")
    add_condition(out, GiNaC::cos(a), Need::nonzero, "cos of tan's argument");
  else if (name == "asin" || name == "acos")
    add_condition(out, 1 - GiNaC::pow(a, 2), Need::nonnegative, "1 - (" + name + "'s argument)^2");
}

void collect_conditions(const ex& e, std::vector<Condition>& out) {
  for (std::size_t i = 0; i < e.nops(); ++i) collect_conditions(e.op(i), out);
  if (GiNaC::is_a<GiNaC::power>(e))
    power_conditions(GiNaC::ex_to<GiNaC::power>(e), out);
  else if (GiNaC::is_a<GiNaC::function>(e))
    function_conditions(GiNaC::ex_to<GiNaC::function>(e), out);
}

std::string requirement_text(const Condition& c) {
  static const char* ops[] = {"!= 0", ">= 0", "> 0"};
  return fmt::format("{} {} ({})", to_string(c.arg), ops[static_cast<int>(c.need)], c.what);
}

// ----- deciding one condition on the box: bisection in Arb balls --------------------------

enum class BallSign { holds, fails, unknown };

// Whether the condition holds on every point of the ball, fails on every point, or neither.
BallSign judge(arb_srcptr b, Need need) {
  switch (need) {
    case Need::nonzero:
      if (!arb_contains_zero(b)) return BallSign::holds;
      return arb_is_zero(b) ? BallSign::fails : BallSign::unknown;
    case Need::nonnegative:
      if (arb_is_nonnegative(b)) return BallSign::holds;
      return arb_is_negative(b) ? BallSign::fails : BallSign::unknown;
    case Need::positive:
      if (arb_is_positive(b)) return BallSign::holds;
      return arb_is_nonpositive(b) ? BallSign::fails : BallSign::unknown;
  }
  return BallSign::unknown;
}

struct SubBox {
  std::vector<double> lo, hi;
  std::vector<double> centre() const {
    std::vector<double> c(lo.size());
    for (std::size_t k = 0; k < lo.size(); ++k) c[k] = 0.5 * (lo[k] + hi[k]);
    return c;
  }
};

struct Bisection {
  std::vector<SubBox> failing;  // proved to fail on the whole sub-box
  std::vector<SubBox> unknown;  // neither proved nor excluded when the budget ended
  bool any_holds = false;
};

constexpr std::size_t kMaxBoxes = 512;
constexpr int kMaxSplits = 40;  // per variable: sub-boxes stay wider than 2^-40 of the box

std::size_t widest_used(const SubBox& b, const std::vector<bool>& used) {
  std::size_t best = 0;
  double width = -1;
  for (std::size_t k = 0; k < b.lo.size(); ++k)
    if (used[k] && b.hi[k] - b.lo[k] > width) width = b.hi[k] - b.lo[k], best = k;
  return best;
}

Bisection bisect(Tape& tape, const Box& box, Need need) {
  Bisection r;
  SubBox all;
  for (const auto& rg : box.ranges) all.lo.push_back(rg.lo), all.hi.push_back(rg.hi);
  const std::vector<bool> used = tape.used_vars();
  const int max_depth = kMaxSplits * static_cast<int>(std::count(used.begin(), used.end(), true));
  std::deque<std::pair<SubBox, int>> queue{{all, 0}};
  BallVec out(1);
  for (std::size_t evaluated = 0; !queue.empty(); ++evaluated) {
    auto [b, depth] = queue.front();
    queue.pop_front();
    const BallSign s = tape.eval_box(b.lo, b.hi, out) ? judge(out[0], need) : BallSign::unknown;
    if (s == BallSign::holds) r.any_holds = true;
    if (s == BallSign::fails) r.failing.push_back(b);
    if (s != BallSign::unknown) continue;
    if (evaluated >= kMaxBoxes || depth >= max_depth) {
      r.unknown.push_back(b);
      continue;
    }
    const std::size_t k = widest_used(b, used);
    SubBox left = b, right = b;
    left.hi[k] = right.lo[k] = 0.5 * (b.lo[k] + b.hi[k]);
    queue.push_back({left, depth + 1});
    queue.push_back({right, depth + 1});
  }
  return r;
}

// Smallest box holding the sub-boxes, as "x1 in [a, b], ..." over the variables where it is
// narrower than the domain box ("the whole box" when none is).
std::string hull_text(const std::vector<SubBox>& boxes, const Box& box) {
  std::vector<std::string> parts;
  for (std::size_t k = 0; k < box.vars.size(); ++k) {
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (const auto& b : boxes) lo = std::min(lo, b.lo[k]), hi = std::max(hi, b.hi[k]);
    if (lo > box.ranges[k].lo || hi < box.ranges[k].hi)
      parts.push_back(fmt::format("{} in [{:.4g}, {:.4g}]", box.vars[k].get_name(), lo, hi));
  }
  return parts.empty() ? std::string("sub-boxes spread over the whole box")
                       : fmt::format("{}", fmt::join(parts, ", "));
}

std::string point_text(const std::vector<double>& x, const Box& box) {
  std::vector<std::string> parts;
  for (std::size_t k = 0; k < x.size(); ++k)
    parts.push_back(fmt::format("{} = {:.6g}", box.vars[k].get_name(), x[k]));
  return fmt::format("{}", fmt::join(parts, ", "));
}

// A point of an undecided sub-box where the condition provably fails (its centre or a corner,
// evaluated as exact points), or a sign change of a continuous argument across the sub-box: a
// proof that the failure set meets the box.
std::string failure_witness(Tape& tape, const SubBox& b, const Box& box, Need need) {
  BallVec out(1);
  for (const auto& x : {b.centre(), b.lo, b.hi})
    if (tape.eval_point(x, out) && judge(out[0], need) == BallSign::fails)
      return fmt::format("fails at {} (exact point evaluation)", point_text(x, box));
  BallVec lo(1), hi(1), whole(1);
  if (need == Need::nonzero && tape.eval_box(b.lo, b.hi, whole) && tape.eval_point(b.lo, lo) &&
      tape.eval_point(b.hi, hi) &&
      ((arb_is_positive(lo[0]) && arb_is_negative(hi[0])) ||
       (arb_is_negative(lo[0]) && arb_is_positive(hi[0]))))
    return fmt::format(
        "changes sign between {} and {} and is continuous there (so vanishes "
        "in between)",
        point_text(b.lo, box), point_text(b.hi, box));
  return "";
}

// A condition on one variable is decided from its range directly (Arb's balls for an interval
// reach a rounding error past its endpoints, so sqrt(x1) on x1 in [0, 1] would stay unproved).
std::optional<DefinednessFinding> decide_on_variable(const Condition& c, std::size_t k,
                                                     const Box& box) {
  const double lo = box.ranges[k].lo, hi = box.ranges[k].hi;
  const bool holds = c.need == Need::nonzero       ? (lo > 0 || hi < 0)
                     : c.need == Need::nonnegative ? lo >= 0
                                                   : lo > 0;
  if (holds) return std::nullopt;
  const bool nowhere = c.need == Need::nonzero       ? (lo == 0 && hi == 0)
                       : c.need == Need::nonnegative ? hi < 0
                                                     : hi <= 0;
  DefinednessFinding f;
  f.requirement = requirement_text(c);
  const std::string name = box.vars[k].get_name();
  f.status = nowhere ? DefinedStatus::violated_everywhere : DefinedStatus::violated_somewhere;
  // A failing point: the zero of x != 0, the lower end for x >= 0, the nonpositive end for x > 0.
  const double bad = c.need == Need::nonzero       ? 0
                     : c.need == Need::nonnegative ? lo
                                                   : std::min(hi, 0.0);
  f.sub_box = c.need == Need::nonzero ? fmt::format("{} = 0", name)
              : c.need == Need::nonnegative
                  ? fmt::format("{} in [{:.4g}, {:.4g})", name, lo, std::min(hi, 0.0))
                  : fmt::format("{} in [{:.4g}, {:.4g}]", name, lo, std::min(hi, 0.0));
  f.witness = fmt::format("fails at {} = {:.6g} (the box's range of {} is [{:.6g}, {:.6g}])", name,
                          bad, name, lo, hi);
  return f;
}

// Nonnegative (or positive, `strict`) by its form alone, whatever the box: even powers, abs,
// exp, roots, and sums and products of such terms (x1^2 at x1 = 0 is exactly 0, which a ball
// reaching a rounding error below zero cannot show).
bool nonnegative_by_form(const ex& e, bool strict) {
  if (GiNaC::is_a<GiNaC::numeric>(e)) {
    const auto v = GiNaC::ex_to<GiNaC::numeric>(e);
    return v.is_real() && (strict ? v.is_positive() : !v.is_negative());
  }
  if (GiNaC::is_a<GiNaC::power>(e)) {
    const ex k = e.op(1);
    if (!GiNaC::is_a<GiNaC::numeric>(k)) return false;
    const auto q = GiNaC::ex_to<GiNaC::numeric>(k);
    if (q.is_even()) return !strict;
    return !q.is_integer() && nonnegative_by_form(e.op(0), strict);  // a root of its own domain
  }
  if (GiNaC::is_a<GiNaC::function>(e)) {
    const std::string name = GiNaC::ex_to<GiNaC::function>(e).get_name();
    return name == "exp" || name == "cosh" || (!strict && name == "abs");
  }
  const bool sum = GiNaC::is_a<GiNaC::add>(e), product = GiNaC::is_a<GiNaC::mul>(e);
  if (!sum && !product) return false;
  bool any_strict = false;
  for (std::size_t i = 0; i < e.nops(); ++i) {
    if (!nonnegative_by_form(e.op(i), false)) return false;
    any_strict = any_strict || nonnegative_by_form(e.op(i), true);
  }
  if (!strict) return true;
  if (sum) return any_strict;
  for (std::size_t i = 0; i < e.nops(); ++i)
    if (!nonnegative_by_form(e.op(i), true)) return false;
  return true;
}

// nullopt: the condition holds on the whole box (proved).
std::optional<DefinednessFinding> decide(const Condition& c, const Box& box) {
  if (c.need != Need::nonzero && nonnegative_by_form(c.arg, c.need == Need::positive))
    return std::nullopt;
  for (std::size_t k = 0; k < box.vars.size(); ++k)
    if (c.arg.is_equal(box.vars[k])) return decide_on_variable(c, k, box);
  DefinednessFinding f;
  f.requirement = requirement_text(c);
  Tape tape({c.arg}, box.vars);
  if (!tape.supported()) {
    f.sub_box = "the whole box";
    f.witness = "not decided: " + tape.why();
    return f;
  }
  Bisection r = bisect(tape, box, c.need);
  if (r.failing.empty() && r.unknown.empty()) return std::nullopt;
  std::vector<SubBox> where = r.failing;
  where.insert(where.end(), r.unknown.begin(), r.unknown.end());
  f.sub_box = hull_text(where, box);
  if (!r.failing.empty()) {
    f.status = r.unknown.empty() && !r.any_holds ? DefinedStatus::violated_everywhere
                                                 : DefinedStatus::violated_somewhere;
    f.witness = fmt::format(
        "fails on all of {}{} (proved in Arb balls)", hull_text({r.failing.front()}, box),
        r.failing.size() > 1 ? fmt::format(" and of {} other sub-boxes", r.failing.size() - 1)
                             : std::string());
    return f;
  }
  for (const auto& b : r.unknown) {
    f.witness = failure_witness(tape, b, box, c.need);
    if (f.witness.empty()) continue;
    f.status = DefinedStatus::violated_somewhere;
    return f;
  }
  f.status = DefinedStatus::not_excluded;
  f.witness = fmt::format("not excluded by Arb balls on {} sub-boxes", r.unknown.size());
  return f;
}

// ----- magnitudes -------------------------------------------------------------------------

void check_coefficients(const ex& e, const std::string& component, const SourceLoc& loc,
                        std::vector<Diagnostic>& out) {
  if (GiNaC::is_a<GiNaC::numeric>(e)) {
    const double v = std::abs(GiNaC::ex_to<GiNaC::numeric>(e).to_double());
    if (v == 0 || (v >= 1 / kMagnitudeLimit && v <= kMagnitudeLimit)) return;
    out.push_back({Severity::error, loc,
                   fmt::format("{} has the coefficient {:.3g}, outside [1e-150, 1e150] in "
                               "magnitude: double-precision certificates and the generated code "
                               "square it; rescale the states, inputs or time",
                               component, GiNaC::ex_to<GiNaC::numeric>(e).to_double())});
    return;
  }
  for (std::size_t i = 0; i < e.nops(); ++i) check_coefficients(e.op(i), component, loc, out);
}

// The largest finite |e| at deterministic sample points; a value beyond the limit (or an
// overflow to infinity where the component's conditions all hold) is an error.
void check_values(const ex& e, const std::string& component, const SourceLoc& loc, const Box& box,
                  bool conditions_hold, std::vector<Diagnostic>& out) {
  Tape tape({e}, box.vars);
  std::vector<double> v(1);
  for (const auto& x : sample_points(box, 256)) {
    tape.eval_double(x, v);
    const bool overflow = std::isinf(v[0]) && conditions_hold;
    if (!overflow && !(std::isfinite(v[0]) && std::abs(v[0]) > kMagnitudeLimit)) continue;
    out.push_back(
        {Severity::error, loc,
         fmt::format("{} = {} reaches |{}| = {:.3g} at {}, beyond 1e150: "
                     "double-precision certificates and the generated code square "
                     "it; rescale the states, inputs or time",
                     component, to_string(e), component, std::abs(v[0]), point_text(x, box))});
    return;
  }
}

struct Component {
  std::string name;
  ex expr;
  SourceLoc loc;
};

std::vector<Component> components(const Model& m) {
  std::vector<Component> out;
  auto loc = [&](const std::string& key) {
    const auto it = m.locations.find(key);
    if (it != m.locations.end()) return it->second;
    const auto whole = m.locations.find(key.substr(0, 1));
    return whole != m.locations.end() ? whole->second : SourceLoc{m.file, 0, 0};
  };
  const ExVec field = m.field();
  for (std::size_t i = 0; i < field.size(); ++i)
    out.push_back({fmt::format("f{}", i + 1), field[i], loc(fmt::format("f[{}]", i))});
  const ExVec y = m.measured_outputs();
  for (std::size_t i = 0; i < y.size(); ++i)
    out.push_back({fmt::format("h{}", i + 1), y[i], loc(fmt::format("h[{}]", i))});
  return out;
}

}  // namespace

std::string DefinednessFinding::text() const {
  const std::string head = fmt::format("{} = {} needs {}", component, expression, requirement);
  switch (status) {
    case DefinedStatus::violated_everywhere:
      return head + ", which fails on the whole domain box (proved in Arb balls)";
    case DefinedStatus::violated_somewhere:
      return fmt::format("{}, which fails inside the domain box, on {}: {}", head, sub_box,
                         witness);
    case DefinedStatus::not_excluded:
      break;
  }
  return fmt::format("{}, not proved on {} ({})", head, sub_box, witness);
}

std::string DefinednessFinding::short_text() const {
  return fmt::format("{} needs {}, which fails on {}", component, requirement, sub_box);
}

bool Definedness::undefined_somewhere() const {
  for (const auto& f : findings)
    if (f.status != DefinedStatus::not_excluded) return true;
  return false;
}

std::vector<Diagnostic> Definedness::errors() const {
  std::vector<Diagnostic> out = magnitude_errors;
  for (const auto& f : findings)
    if (f.status == DefinedStatus::violated_everywhere)
      out.push_back(
          {Severity::error, f.loc, f.text() + " (the model is undefined on its whole domain box)"});
  return out;
}

std::string Definedness::summary() const {
  if (findings.empty() && conditions == 0)
    return "defined everywhere (no division, root, log or tan)";
  if (findings.empty())
    return fmt::format("defined on the domain box ({} condition{} proved)", conditions,
                       conditions == 1 ? "" : "s");
  std::vector<std::string> parts;
  for (const auto& f : findings) parts.push_back(f.text());
  return fmt::format("{}", fmt::join(parts, "; "));
}

namespace {

// A box endpoint beyond the limit, or nonzero below its inverse, leaves the sampled and
// certified figures (widths, their squares) no headroom either.
void check_box(const Model& m, std::vector<Diagnostic>& out) {
  const auto it = m.locations.find("domain");
  const SourceLoc loc = it != m.locations.end() ? it->second : SourceLoc{m.file, 0, 0};
  auto outside = [](double v) {
    const double a = std::abs(v);
    return a != 0 && (a > kMagnitudeLimit || a < 1 / kMagnitudeLimit);
  };
  for (const auto& s : m.all_symbols()) {
    const Interval iv = m.box(s);
    const double lo = iv.lo.to_double(), hi = iv.hi.to_double();
    if (!outside(lo) && !outside(hi)) continue;
    out.push_back({Severity::error, loc,
                   fmt::format("the box of {} is [{:.3g}, {:.3g}]: an endpoint outside [1e-150, "
                               "1e150] in magnitude leaves double precision no headroom; rescale "
                               "{}",
                               s.get_name(), lo, hi, s.get_name())});
  }
}

}  // namespace

Definedness check_definedness(const Model& m) {
  Definedness d;
  check_box(m, d.magnitude_errors);
  // The magnitudes are sampled at the box's points as doubles; the conditions need the box
  // rounded outward (Arb), built only when there is one (a polynomial model never loads FLINT).
  Box sample_box;
  for (const auto& s : m.all_symbols()) {
    const Interval iv = m.box(s);
    sample_box.vars.push_back(s);
    sample_box.ranges.push_back({iv.lo.to_double(), iv.hi.to_double()});
  }
  std::optional<Box> outward;
  for (const auto& c : components(m)) {
    const std::size_t coefficient_errors = d.magnitude_errors.size();
    check_coefficients(c.expr, c.name, c.loc, d.magnitude_errors);
    std::vector<Condition> conditions;
    collect_conditions(c.expr, conditions);
    d.conditions += conditions.size();
    bool all_hold = true;
    for (const auto& cond : conditions) {
      if (!outward) outward = model_box(m);
      std::optional<DefinednessFinding> f = decide(cond, *outward);
      if (!f) continue;
      all_hold = false;
      f->component = c.name;
      f->expression = to_string(c.expr);
      f->loc = c.loc;
      d.findings.push_back(std::move(*f));
    }
    if (d.magnitude_errors.size() == coefficient_errors)  // one diagnostic per cause
      check_values(c.expr, c.name, c.loc, sample_box, all_hold, d.magnitude_errors);
  }
  return d;
}

}  // namespace obsynth::certify
