#include "certify/tape.hpp"

#include <flint/fmpq.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <sstream>
#include <stdexcept>

namespace obsynth::certify::detail {

using GiNaC::ex;
using GiNaC::numeric;

namespace {

// RAII arf.
struct Arf {
  Arf() { arf_init(v); }
  ~Arf() { arf_clear(v); }
  Arf(const Arf&) = delete;
  Arf& operator=(const Arf&) = delete;
  arf_t v;
};
struct Ball {
  Ball() { arb_init(v); }
  ~Ball() { arb_clear(v); }
  Ball(const Ball&) = delete;
  Ball& operator=(const Ball&) = delete;
  arb_t v;
};

void set_rational(arb_ptr r, const numeric& v) {
  fmpq_t q;
  fmpq_init(q);
  std::ostringstream a, b;
  a << v.numer();
  b << v.denom();
  const std::string num = a.str(), den = b.str();
  fmpz_set_str(fmpq_numref(q), num.c_str(), 10);
  fmpz_set_str(fmpq_denref(q), den.c_str(), 10);
  fmpq_canonicalise(q);
  arb_set_fmpq(r, q, kPrec);
  fmpq_clear(q);
}

// r = [lo, hi] from two balls enclosing the endpoints.
void set_hull(arb_ptr r, arb_srcptr lo_ball, arb_srcptr hi_ball) {
  Arf a, b;
  arb_get_lbound_arf(a.v, lo_ball, kPrec);
  arb_get_ubound_arf(b.v, hi_ball, kPrec);
  arb_set_interval_arf(r, a.v, b.v, kPrec);
}

// Endpoints of a ball as exact point balls.
void endpoints(arb_srcptr x, arb_ptr lo, arb_ptr hi) {
  Arf a, b;
  arb_get_lbound_arf(a.v, x, kPrec);
  arb_get_ubound_arf(b.v, x, kPrec);
  arb_set_arf(lo, a.v);
  arb_set_arf(hi, b.v);
}

// Integer power with interval tightness (x^2 on [-1, 2] is [0, 4], not a midpoint-radius ball
// reaching below zero).
bool pow_int(arb_ptr r, arb_srcptr x, long k) {
  if (k == 0) {
    arb_one(r);
    return true;
  }
  const unsigned long n = static_cast<unsigned long>(k < 0 ? -k : k);
  Ball lo, hi, plo, phi;
  endpoints(x, lo.v, hi.v);
  arb_pow_ui(plo.v, lo.v, n, kPrec);
  arb_pow_ui(phi.v, hi.v, n, kPrec);
  if (n % 2 == 1 || arb_is_nonnegative(lo.v)) {
    set_hull(r, plo.v, phi.v);
  } else if (arb_is_nonpositive(hi.v)) {
    set_hull(r, phi.v, plo.v);
  } else {
    Ball z, m;
    arb_zero(z.v);
    arb_abs(lo.v, lo.v);
    arb_max(m.v, lo.v, hi.v, kPrec);
    arb_pow_ui(m.v, m.v, n, kPrec);
    set_hull(r, z.v, m.v);
  }
  if (k < 0) {
    if (arb_contains_zero(r)) return false;
    arb_inv(r, r, kPrec);
  }
  return arb_is_finite(r);
}

// x^(p/q), q > 1, real only for x >= 0 (GiNaC's principal value is complex for x < 0).
// Natural-domain semantics: the enclosure covers the points of the ball where the power is
// defined (a ball [0, 4] comes out of Arb as [-3.7e-9, 4.0000001]: its negative sliver has
// no real value).
bool pow_rat(arb_ptr r, arb_srcptr x, long p, long q, bool& clamped) {
  Ball lo, hi;
  endpoints(x, lo.v, hi.v);
  if (arb_is_negative(hi.v)) return false;
  if (arb_is_negative(lo.v)) {
    arb_zero(lo.v);
    clamped = true;
  }
  if (p < 0 && !arb_is_positive(lo.v)) return false;
  fmpq_t a;
  fmpq_init(a);
  fmpq_set_si(a, p, static_cast<ulong>(q));
  Ball plo, phi;
  if (arb_is_zero(lo.v))
    arb_zero(plo.v);
  else
    arb_pow_fmpq(plo.v, lo.v, a, kPrec);
  arb_pow_fmpq(phi.v, hi.v, a, kPrec);
  fmpq_clear(a);
  if (p > 0)
    set_hull(r, plo.v, phi.v);
  else
    set_hull(r, phi.v, plo.v);
  return arb_is_finite(r);
}

bool abs_tight(arb_ptr r, arb_srcptr x) {
  Ball lo, hi;
  endpoints(x, lo.v, hi.v);
  if (arb_is_nonnegative(lo.v)) {
    arb_set(r, x);
  } else if (arb_is_nonpositive(hi.v)) {
    arb_neg(r, x);
  } else {
    Ball z, m;
    arb_zero(z.v);
    arb_abs(lo.v, lo.v);
    arb_max(m.v, lo.v, hi.v, kPrec);
    set_hull(r, z.v, m.v);
  }
  return arb_is_finite(r);
}

std::string text_of(const ex& e) {
  std::ostringstream os;
  os << e;
  return os.str();
}

// The op of a function of one argument that balls evaluate; nullopt for others.
std::optional<Tape::Op> function_op(const std::string& name) {
  static const std::map<std::string, Tape::Op> fns = {
      {"sin", Tape::Op::sin},   {"cos", Tape::Op::cos}, {"tan", Tape::Op::tan},
      {"exp", Tape::Op::exp},   {"log", Tape::Op::log}, {"tanh", Tape::Op::tanh},
      {"atan", Tape::Op::atan}, {"abs", Tape::Op::abs}};
  auto it = fns.find(name);
  if (it == fns.end()) return std::nullopt;
  return it->second;
}

// One node's ball r from its arguments' balls arg(k) (var and cst nodes are set by the
// caller); t is scratch. False where the op is undefined on the ball.
template <class Arg>
bool eval_op(const Tape::Node& n, arb_ptr r, const Arg& arg, Ball& t, bool& clamped) {
  using Op = Tape::Op;
  switch (n.op) {
    case Op::var:
    case Op::cst:
      return true;
    case Op::add:
      arb_set(t.v, arg(0));
      for (std::size_t k = 1; k < n.args.size(); ++k) arb_add(t.v, t.v, arg(k), kPrec);
      arb_swap(r, t.v);
      return true;
    case Op::mul:
      arb_set(t.v, arg(0));
      for (std::size_t k = 1; k < n.args.size(); ++k) arb_mul(t.v, t.v, arg(k), kPrec);
      arb_swap(r, t.v);
      return true;
    case Op::powi:
      return pow_int(r, arg(0), n.var);
    case Op::powq:
      return pow_rat(r, arg(0), n.p, n.q, clamped);
    case Op::powgen:
      if (!arb_is_positive(arg(0))) return false;
      arb_log(t.v, arg(0), kPrec);
      arb_mul(t.v, t.v, arg(1), kPrec);
      arb_exp(r, t.v, kPrec);
      return true;
    case Op::sin:
      arb_sin(r, arg(0), kPrec);
      return true;
    case Op::cos:
      arb_cos(r, arg(0), kPrec);
      return true;
    case Op::tan:
      arb_tan(r, arg(0), kPrec);
      return true;
    case Op::exp:
      arb_exp(r, arg(0), kPrec);
      return true;
    case Op::log:
      if (!arb_is_positive(arg(0))) return false;
      arb_log(r, arg(0), kPrec);
      return true;
    case Op::tanh:
      arb_tanh(r, arg(0), kPrec);
      return true;
    case Op::atan:
      arb_atan(r, arg(0), kPrec);
      return true;
    case Op::abs:
      return abs_tight(r, arg(0));
  }
  return true;
}

}  // namespace

double upper(arb_srcptr x) {
  if (!arb_is_finite(x)) return std::numeric_limits<double>::infinity();
  Arf u;
  arb_get_ubound_arf(u.v, x, kPrec);
  return arf_get_d(u.v, ARF_RND_CEIL);
}
double lower(arb_srcptr x) {
  if (!arb_is_finite(x)) return -std::numeric_limits<double>::infinity();
  Arf u;
  arb_get_lbound_arf(u.v, x, kPrec);
  return arf_get_d(u.v, ARF_RND_FLOOR);
}
double abs_upper(arb_srcptr x) {
  if (!arb_is_finite(x)) return std::numeric_limits<double>::infinity();
  Arf u;
  arb_get_abs_ubound_arf(u.v, x, kPrec);
  return arf_get_d(u.v, ARF_RND_CEIL);
}

double rational_lower(const numeric& v) {
  Ball b;
  set_rational(b.v, v);
  return lower(b.v);
}
double rational_upper(const numeric& v) {
  Ball b;
  set_rational(b.v, v);
  return upper(b.v);
}

Tape::Tape(const std::vector<ex>& outputs, const std::vector<GiNaC::symbol>& vars)
    : nvars_(vars.size()) {
  Dag dag;
  std::vector<int> roots;
  for (const auto& o : outputs) roots.push_back(dag.add(o));
  std::vector<int> done(dag.size(), -1);
  for (int r : roots) outputs_.push_back(lower(dag, r, vars, done));
}

// The balls of the constants, on the first ball evaluation: a tape used only in doubles (the
// definedness stage's magnitudes) never loads FLINT and Arb (lazy_libraries.cpp).
void Tape::init_balls() {
  if (balls_ready_) return;
  balls_ready_ = true;
  consts_ = BallVec(nodes_.size());
  work_ = BallVec(nodes_.size());
  if (!supported()) return;
  for (std::size_t i = 0; i < nodes_.size(); ++i) {
    const Node& n = nodes_[i];
    if (n.op != Op::cst) continue;
    if (n.var != 0) {  // +-pi
      arb_const_pi(consts_[i], kPrec);
      if (n.var < 0) arb_neg(consts_[i], consts_[i]);
      continue;
    }
    const numeric& v = constants_[i];
    if (!v.is_real()) continue;
    if (v.is_rational()) {
      set_rational(consts_[i], v);
    } else {
      // A float: its decimal expansion, read by Arb with rigorous rounding.
      std::ostringstream os;
      os << v;
      if (arb_set_str(consts_[i], os.str().c_str(), kPrec) != 0)
        why_ = "cannot read the number " + os.str();
    }
  }
}

// The tape is symbolic/dag's DAG (the project's one GiNaC-to-DAG conversion: hash-consed, in a
// canonical operand order, so the tape, its rounding and every reported digit are deterministic)
// lowered to the ops that balls evaluate, the needed nodes only, in the DAG's order.
int Tape::lower(const Dag& dag, int id, const std::vector<GiNaC::symbol>& vars,
                std::vector<int>& done) {
  if (done[static_cast<std::size_t>(id)] >= 0) return done[static_cast<std::size_t>(id)];
  const obsynth::Node& d = dag.node(id);
  std::vector<int> args;
  for (int a : d.args) args.push_back(lower(dag, a, vars, done));
  Node n{Op::cst, {}, 0, 0, 1, 0};
  auto push = [&](Node x) {
    nodes_.push_back(std::move(x));
    constants_.emplace_back();
    return static_cast<int>(nodes_.size()) - 1;
  };
  switch (d.op) {
    case NodeOp::constant: {
      // pi reaches the DAG as its decimal value: an exact ball of pi keeps the enclosure rigorous.
      static const numeric pi = GiNaC::ex_to<numeric>(GiNaC::evalf(GiNaC::Pi));
      if (GiNaC::abs(d.value) == pi) {
        n.var = d.value.is_negative() ? -1 : 1;
        n.dval = d.value.is_negative() ? -M_PI : M_PI;
      } else {
        if (!d.value.is_real()) why_ = "complex constant " + text_of(d.value);
        n.dval = d.value.is_real() ? d.value.to_double() : std::nan("");
      }
      const int k = push(n);
      constants_[static_cast<std::size_t>(k)] = d.value;
      return done[static_cast<std::size_t>(id)] = k;
    }
    case NodeOp::variable: {
      std::size_t i = 0;
      while (i < vars.size() && vars[i].get_name() != d.name) ++i;
      if (i == vars.size())
        throw std::invalid_argument("certify: the symbol '" + d.name +
                                    "' is not a variable of the box");
      n.op = Op::var;
      n.var = static_cast<long>(i);
      break;
    }
    case NodeOp::add:
    case NodeOp::mul:
      n.op = d.op == NodeOp::add ? Op::add : Op::mul;
      n.args = args;
      break;
    case NodeOp::div: {  // a / b = a * b^-1
      Node inv{Op::powi, {args[1]}, -1, 0, 1, 0};
      n.op = Op::mul;
      n.args = {args[0], push(inv)};
      break;
    }
    case NodeOp::neg: {  // -a = (-1) * a
      Node m1{Op::cst, {}, 0, 0, 1, -1.0};
      const int k = push(m1);
      constants_[static_cast<std::size_t>(k)] = numeric(-1);
      n.op = Op::mul;
      n.args = {k, args[0]};
      break;
    }
    case NodeOp::pow_int:
      n.op = Op::powi;
      n.var = d.exponent;
      n.args = args;
      break;
    case NodeOp::sqrt:
    case NodeOp::pow_real:
      n.op = Op::powq;
      n.p = d.op == NodeOp::sqrt ? 1 : d.value.numer().to_long();
      n.q = d.op == NodeOp::sqrt ? 2 : d.value.denom().to_long();
      if (d.op == NodeOp::pow_real && !d.value.is_rational()) why_ = "irrational exponent";
      n.args = args;
      break;
    case NodeOp::call:
      if (const auto op = function_op(d.name)) {
        n.op = *op;
        n.args = args;
      } else {
        why_ = "function " + d.name;
      }
      break;
  }
  return done[static_cast<std::size_t>(id)] = push(n);
}

bool Tape::eval_box(const std::vector<double>& lo, const std::vector<double>& hi, BallVec& out) {
  init_balls();
  Arf a, b;
  for (std::size_t i = 0; i < nodes_.size(); ++i) {
    if (nodes_[i].op != Op::var) continue;
    const auto k = static_cast<std::size_t>(nodes_[i].var);
    arf_set_d(a.v, lo[k]);
    arf_set_d(b.v, hi[k]);
    arb_set_interval_arf(work_[i], a.v, b.v, kPrec);
  }
  return run(out);
}

bool Tape::eval_point(const std::vector<double>& x, BallVec& out) {
  init_balls();
  for (std::size_t i = 0; i < nodes_.size(); ++i)
    if (nodes_[i].op == Op::var) arb_set_d(work_[i], x[static_cast<std::size_t>(nodes_[i].var)]);
  return run(out);
}

bool Tape::run(BallVec& out) {
  clamped_ = false;
  if (!supported()) return false;
  Ball t;
  for (std::size_t i = 0; i < nodes_.size(); ++i) {
    const Node& n = nodes_[i];
    arb_ptr r = work_[i];
    auto arg = [&](std::size_t k) { return work_[static_cast<std::size_t>(n.args[k])]; };
    if (n.op == Op::cst) arb_set(r, consts_[i]);
    if (!eval_op(n, r, arg, t, clamped_) || !arb_is_finite(r)) return false;
  }
  if (out.size() != outputs_.size()) out = BallVec(outputs_.size());
  for (std::size_t k = 0; k < outputs_.size(); ++k)
    arb_set(out[k], work_[static_cast<std::size_t>(outputs_[k])]);
  return true;
}

void Tape::eval_double(const std::vector<double>& x, std::vector<double>& out) const {
  std::vector<double> w(nodes_.size());
  for (std::size_t i = 0; i < nodes_.size(); ++i) {
    const Node& n = nodes_[i];
    auto arg = [&](std::size_t k) { return w[static_cast<std::size_t>(n.args[k])]; };
    double r = 0;
    switch (n.op) {
      case Op::var:
        r = x[static_cast<std::size_t>(n.var)];
        break;
      case Op::cst:
        r = n.dval;
        break;
      case Op::add:
        r = 0;
        for (std::size_t k = 0; k < n.args.size(); ++k) r += arg(k);
        break;
      case Op::mul:
        r = 1;
        for (std::size_t k = 0; k < n.args.size(); ++k) r *= arg(k);
        break;
      case Op::powi:
        r = std::pow(arg(0), static_cast<double>(n.var));
        break;
      case Op::powq:
        r = arg(0) < 0 ? std::nan("")
                       : std::pow(arg(0), static_cast<double>(n.p) / static_cast<double>(n.q));
        break;
      case Op::powgen:
        r = arg(0) <= 0 ? std::nan("") : std::exp(arg(1) * std::log(arg(0)));
        break;
      case Op::sin:
        r = std::sin(arg(0));
        break;
      case Op::cos:
        r = std::cos(arg(0));
        break;
      case Op::tan:
        r = std::tan(arg(0));
        break;
      case Op::exp:
        r = std::exp(arg(0));
        break;
      case Op::log:
        r = arg(0) <= 0 ? std::nan("") : std::log(arg(0));
        break;
      case Op::tanh:
        r = std::tanh(arg(0));
        break;
      case Op::atan:
        r = std::atan(arg(0));
        break;
      case Op::abs:
        r = std::fabs(arg(0));
        break;
    }
    w[i] = r;
  }
  out.resize(outputs_.size());
  for (std::size_t k = 0; k < outputs_.size(); ++k)
    out[k] = w[static_cast<std::size_t>(outputs_[k])];
}

}  // namespace obsynth::certify::detail
