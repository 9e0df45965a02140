#include "analysis/jets_rank.hpp"

#include <arb.h>
#include <flint/nmod.h>
#include <flint/nmod_vec.h>
#include <flint/ulong_extras.h>
#include <fmt/format.h>

#include <cln/integer.h>
#include <cln/integer_io.h>
#include <algorithm>
#include <cmath>
#include <sstream>
#include <unordered_map>

#include "symbolic/dag.hpp"
#include "symbolic/expr_print.hpp"
#include "symbolic/lie.hpp"
#include "symbolic/zero_test.hpp"

namespace obsynth {

using GiNaC::ex;
using GiNaC::numeric;

namespace {

// ---------------------------------------------------------------------------------------------
// The expression DAG: binary add/mul, unary functions; shared subtrees are one node.

enum class Op {
  constant,
  state,
  symbol,
  add,
  mul,
  inv,
  pow_rat,
  exp,
  log,
  sin,
  cos,
  tan,
  tanh,
  atan
};

struct Node {
  Op op = Op::constant;
  int a = -1, b = -1;  // operands
  int index = 0;       // state or symbol index
  numeric value;       // constant value, or the exponent of pow_rat
};

// The evaluators' program: the project's one GiNaC-to-DAG conversion (symbolic/dag, hash-consed
// and order-independent) lowered to binary add/mul, inversion, rational powers and the unary
// functions that Taylor arithmetic over a field implements.
class Program {
 public:
  Program(const Symbols& states, const Symbols& symbols, const Model& m)
      : states_(states), symbols_(symbols), model_(m) {}

  int add(const ex& e) {
    const int id = source_.add(e);
    try {
      return lower(id);
    } catch (const UnsupportedNode& u) {
      throw UserError(SourceLoc{model_.file, 0, 0},
                      fmt::format("the jets rank cannot evaluate {} in '{}' (supported: + - * / "
                                  "^, sin, cos, tan, exp, log, sqrt, tanh, atan)",
                                  u.what, to_string(e)));
    }
  }
  const std::vector<Node>& nodes() const { return nodes_; }
  bool rational() const { return rational_; }

 private:
  struct UnsupportedNode {
    std::string what;
  };
  int push(Node n) {
    nodes_.push_back(std::move(n));
    return static_cast<int>(nodes_.size()) - 1;
  }
  int constant(const numeric& v) {
    Node n;
    n.value = v;
    return push(n);
  }
  int binary(Op op, int a, int b) {
    Node n;
    n.op = op;
    n.a = a;
    n.b = b;
    return push(n);
  }
  int unary(Op op, int a) {
    rational_ &= op == Op::inv;
    return binary(op, a, -1);
  }
  int integer_power(int base, long k) {
    if (k == 1) return base;
    const int half = integer_power(base, k / 2);
    const int sq = binary(Op::mul, half, half);
    return k % 2 ? binary(Op::mul, sq, base) : sq;
  }
  int fold(Op op, const std::vector<int>& args) {
    int acc = lower(args[0]);
    for (std::size_t i = 1; i < args.size(); ++i) acc = binary(op, acc, lower(args[i]));
    return acc;
  }
  int lower(int id);
  int lower_node(const obsynth::Node& n);
  int variable(const std::string& name);

  const Symbols& states_;
  const Symbols& symbols_;
  const Model& model_;
  Dag source_;
  std::vector<int> lowered_;  // by source node id, -1 until lowered
  std::vector<Node> nodes_;
  bool rational_ = true;
};

int Program::lower(int id) {
  if (lowered_.size() < source_.size()) lowered_.resize(source_.size(), -1);
  int& slot = lowered_[static_cast<std::size_t>(id)];
  if (slot < 0) {
    const int value = lower_node(source_.node(id));
    lowered_[static_cast<std::size_t>(id)] = value;  // the vector may have grown
    return value;
  }
  return slot;
}

int Program::variable(const std::string& name) {
  for (std::size_t i = 0; i < states_.size(); ++i)
    if (states_[i].get_name() == name) {
      Node n;
      n.op = Op::state;
      n.index = static_cast<int>(i);
      return push(n);
    }
  for (std::size_t i = 0; i < symbols_.size(); ++i)
    if (symbols_[i].get_name() == name) {
      Node n;
      n.op = Op::symbol;
      n.index = static_cast<int>(i);
      return push(n);
    }
  for (const auto& p : model_.params)
    if (p.value && p.symbol.get_name() == name) return constant(*p.value);
  throw UnsupportedNode{fmt::format("the symbol '{}'", name)};
}

int Program::lower_node(const obsynth::Node& n) {
  switch (n.op) {
    case NodeOp::constant:
      if (!n.value.is_rational())
        throw UnsupportedNode{fmt::format("the constant {}", to_string(ex(n.value)))};
      return constant(n.value);
    case NodeOp::variable:
      return variable(n.name);
    case NodeOp::add:
      return fold(Op::add, n.args);
    case NodeOp::mul:
      return fold(Op::mul, n.args);
    case NodeOp::div:
      return binary(Op::mul, lower(n.args[0]), unary(Op::inv, lower(n.args[1])));
    case NodeOp::neg:
      return binary(Op::mul, constant(-1), lower(n.args[0]));
    case NodeOp::pow_int:
      return integer_power(lower(n.args[0]), n.exponent);
    case NodeOp::sqrt:
    case NodeOp::pow_real: {
      Node p;
      p.op = Op::pow_rat;
      p.a = lower(n.args[0]);
      p.value = n.op == NodeOp::sqrt ? numeric(1, 2) : n.value;
      rational_ = false;
      return push(p);
    }
    case NodeOp::call: {
      static const std::pair<const char*, Op> table[] = {
          {"exp", Op::exp}, {"log", Op::log},   {"sin", Op::sin},  {"cos", Op::cos},
          {"tan", Op::tan}, {"tanh", Op::tanh}, {"atan", Op::atan}};
      for (const auto& [fn, op] : table)
        if (n.name == fn) return unary(op, lower(n.args[0]));
      throw UnsupportedNode{fmt::format("the function '{}'", n.name)};
    }
  }
  throw UnsupportedNode{"an operation"};
}

// ---------------------------------------------------------------------------------------------
// Degree bounds (numerator, denominator total degree) of a rational DAG's nodes.

struct Degree {
  unsigned long num = 0, den = 0;
};

unsigned long sat_add(unsigned long a, unsigned long b) {
  return a > ~0UL - b ? ~0UL : a + b;
}

std::vector<Degree> degrees(const Program& dag) {
  std::vector<Degree> d(dag.nodes().size());
  for (std::size_t i = 0; i < d.size(); ++i) {
    const Node& n = dag.nodes()[i];
    switch (n.op) {
      case Op::constant:
        break;
      case Op::state:
      case Op::symbol:
        d[i].num = 1;
        break;
      case Op::add: {
        const Degree &a = d[n.a], &b = d[n.b];
        d[i] = {std::max(sat_add(a.num, b.den), sat_add(b.num, a.den)), sat_add(a.den, b.den)};
        break;
      }
      case Op::mul:
        d[i] = {sat_add(d[n.a].num, d[n.b].num), sat_add(d[n.a].den, d[n.b].den)};
        break;
      case Op::inv:
        d[i] = {d[n.a].den, d[n.a].num};
        break;
      default:
        d[i] = {~0UL, ~0UL};  // not rational: no bound
    }
  }
  return d;
}

// Degree bound of the numerator of any maximal minor of O for the field F (roots `field`) and
// outputs `outputs`. With F_i = P_i / Q (Q the product of the F_i's denominators, degree q,
// deg P_i <= p) and h = N / R (degrees a, d): L_F^k h = N_k / (R^(k+1) Q^(2k)) with
// deg N_k <= a + k (d + q + p), and the row of d(L_F^k h) cleared of its denominator has
// degree <= deg N_k + d + q. A maximal minor's numerator is bounded by the sum of the n
// largest row bounds.
unsigned long minor_degree_bound(const std::vector<Degree>& deg, const std::vector<int>& field,
                                 const std::vector<int>& outputs, std::size_t n) {
  unsigned long q = 0, pdeg = 0;
  for (int f : field) q = sat_add(q, deg[f].den);
  for (int f : field) pdeg = std::max(pdeg, sat_add(deg[f].num, q - deg[f].den));
  std::vector<unsigned long> rows;
  for (int h : outputs) {
    const unsigned long step = sat_add(sat_add(deg[h].den, q), pdeg);
    unsigned long nk = deg[h].num;
    for (std::size_t k = 0; k < n; ++k, nk = sat_add(nk, step))
      rows.push_back(sat_add(sat_add(nk, deg[h].den), q));
  }
  std::sort(rows.rbegin(), rows.rend());
  unsigned long total = 0;
  for (std::size_t i = 0; i < n && i < rows.size(); ++i) total = sat_add(total, rows[i]);
  return total;
}

// ---------------------------------------------------------------------------------------------
// Fields: arithmetic modulo a prime, and Arb balls. In-place operations; false = the value is
// undefined at this point (division by zero, a ball containing a pole or a branch cut).

struct ModField {
  using T = mp_limb_t;
  nmod_t mod;
  explicit ModField(mp_limb_t p) { nmod_init(&mod, p); }
  void zero(T& r) const { r = 0; }
  void set(T& r, const T& a) const { r = a; }
  void set_si(T& r, long v) const {
    const mp_limb_t m = static_cast<mp_limb_t>(v < 0 ? -v : v) % mod.n;
    r = v < 0 ? nmod_neg(m, mod) : m;
  }
  bool set_rational(T& r, const numeric& v) const {
    T num, den;
    set_integer(num, v.numer());
    set_integer(den, v.denom());
    if (den == 0) return false;
    r = nmod_mul(num, n_invmod(den, mod.n), mod);
    return true;
  }
  void set_integer(T& r, const numeric& v) const {
    std::ostringstream s;
    s << GiNaC::abs(v);
    fmpz_t z;
    fmpz_init(z);
    fmpz_set_str(z, s.str().c_str(), 10);
    r = fmpz_fdiv_ui(z, mod.n);
    fmpz_clear(z);
    if (v.is_negative()) r = nmod_neg(r, mod);
  }
  void add(T& r, const T& a, const T& b) const { r = nmod_add(a, b, mod); }
  void sub(T& r, const T& a, const T& b) const { r = nmod_sub(a, b, mod); }
  void mul(T& r, const T& a, const T& b) const { r = nmod_mul(a, b, mod); }
  void addmul(T& r, const T& a, const T& b) const { r = nmod_add(r, nmod_mul(a, b, mod), mod); }
  bool inv(T& r, const T& a) const {
    if (a == 0) return false;
    r = n_invmod(a, mod.n);
    return true;
  }
  bool nonzero(const T& a) const { return a != 0; }
  // r += sum_{t < count} a_t b_t for duals a_t = a + t*as, b_t = b + t*bs (W entries each).
  void convolve(T* r, const T* a, long as, const T* b, long bs, std::size_t count,
                std::size_t W) const {
    for (std::size_t t = 0; t < count; ++t, a += as, b += bs) {
      addmul(r[0], a[0], b[0]);
      for (std::size_t c = 1; c < W; ++c)
        r[c] = nmod_add(r[c], nmod_add(nmod_mul(a[0], b[c], mod), nmod_mul(a[c], b[0], mod), mod),
                        mod);
    }
  }
  // Rational models only: never called.
  bool function(Op, T&, T&, const T&) const { return false; }
  bool pow_rat(T&, T&, const T&, const numeric&) const { return false; }
};

// One arb_t: arrays of Ball are arrays of arb_struct (convolve relies on it).
class Ball {
 public:
  Ball() { arb_init(v_); }
  Ball(const Ball& o) {
    arb_init(v_);
    arb_set(v_, o.v_);
  }
  Ball& operator=(const Ball& o) {
    arb_set(v_, o.v_);
    return *this;
  }
  ~Ball() { arb_clear(v_); }
  arb_ptr get() { return v_; }
  arb_srcptr get() const { return v_; }

 private:
  arb_t v_;
};

static_assert(sizeof(Ball) == sizeof(arb_struct), "Ball must be one arb_struct");

void set_fmpz_from(fmpz_t z, const numeric& v) {
  std::ostringstream s;
  s << v;
  fmpz_set_str(z, s.str().c_str(), 10);
}

struct BallField {
  using T = Ball;
  slong prec;
  void zero(T& r) const { arb_zero(r.get()); }
  void set(T& r, const T& a) const { arb_set(r.get(), a.get()); }
  void set_si(T& r, long v) const { arb_set_si(r.get(), v); }
  bool set_rational(T& r, const numeric& v) const {
    fmpq_t q;
    fmpq_init(q);
    set_fmpz_from(fmpq_numref(q), v.numer());
    set_fmpz_from(fmpq_denref(q), v.denom());
    arb_set_fmpq(r.get(), q, prec);
    fmpq_clear(q);
    return true;
  }
  void add(T& r, const T& a, const T& b) const { arb_add(r.get(), a.get(), b.get(), prec); }
  void sub(T& r, const T& a, const T& b) const { arb_sub(r.get(), a.get(), b.get(), prec); }
  void mul(T& r, const T& a, const T& b) const { arb_mul(r.get(), a.get(), b.get(), prec); }
  void addmul(T& r, const T& a, const T& b) const { arb_addmul(r.get(), a.get(), b.get(), prec); }
  bool inv(T& r, const T& a) const {
    if (arb_contains_zero(a.get())) return false;
    arb_inv(r.get(), a.get(), prec);
    return arb_is_finite(r.get());
  }
  bool nonzero(const T& a) const { return !arb_contains_zero(a.get()); }
  // As ModField::convolve, one arb_dot per entry (Ball is layout-compatible with arb_struct).
  void convolve(T* r, const T* a, long as, const T* b, long bs, std::size_t count,
                std::size_t W) const {
    auto p = [](const T* v) { return reinterpret_cast<arb_srcptr>(v); };
    const slong len = static_cast<slong>(count);
    arb_dot(r[0].get(), r[0].get(), 0, p(a), as, p(b), bs, len, prec);
    for (std::size_t c = 1; c < W; ++c) {
      arb_dot(r[c].get(), r[c].get(), 0, p(a), as, p(b + c), bs, len, prec);
      arb_dot(r[c].get(), r[c].get(), 0, p(a + c), as, p(b), bs, len, prec);
    }
  }
  // f(a) and f'(a) for the unary functions (sin: f' = cos, ...).
  bool function(Op op, T& f, T& df, const T& a) const {
    arb_srcptr x = a.get();
    Ball t;
    switch (op) {
      case Op::exp:
        arb_exp(f.get(), x, prec);
        arb_set(df.get(), f.get());
        break;
      case Op::log:
        if (!arb_is_positive(x)) return false;
        arb_log(f.get(), x, prec);
        arb_inv(df.get(), x, prec);
        break;
      case Op::sin:
        arb_sin_cos(f.get(), df.get(), x, prec);
        break;
      case Op::cos:
        arb_sin_cos(df.get(), f.get(), x, prec);
        arb_neg(df.get(), df.get());
        break;
      case Op::tan:  // 1 + tan^2
        arb_tan(f.get(), x, prec);
        arb_sqr(t.get(), f.get(), prec);
        arb_add_ui(df.get(), t.get(), 1, prec);
        break;
      case Op::tanh:  // 1 - tanh^2
        arb_tanh(f.get(), x, prec);
        arb_sqr(t.get(), f.get(), prec);
        arb_sub_ui(df.get(), t.get(), 1, prec);
        arb_neg(df.get(), df.get());
        break;
      case Op::atan:  // 1 / (1 + a^2)
        arb_atan(f.get(), x, prec);
        arb_sqr(t.get(), x, prec);
        arb_add_ui(t.get(), t.get(), 1, prec);
        arb_inv(df.get(), t.get(), prec);
        break;
      default:
        return false;
    }
    return arb_is_finite(f.get()) && arb_is_finite(df.get());
  }
  // a^q and its derivative q a^(q-1), for a > 0.
  bool pow_rat(T& f, T& df, const T& a, const numeric& q) const {
    if (!arb_is_positive(a.get())) return false;
    fmpq_t e;
    fmpq_init(e);
    set_fmpz_from(fmpq_numref(e), q.numer());
    set_fmpz_from(fmpq_denref(e), q.denom());
    arb_pow_fmpq(f.get(), a.get(), e, prec);
    Ball qb;
    arb_set_fmpq(qb.get(), e, prec);
    fmpq_clear(e);
    arb_mul(df.get(), f.get(), qb.get(), prec);
    arb_div(df.get(), df.get(), a.get(), prec);
    return arb_is_finite(f.get()) && arb_is_finite(df.get());
  }
};

// ---------------------------------------------------------------------------------------------
// Taylor coefficients of every node along the trajectory, each a dual number: the value and
// its gradient with respect to x0 (W = n + 1 entries).

template <class F>
class Taylor {
 public:
  using T = typename F::T;
  Taylor(const Program& dag, const F& field, std::size_t n, std::size_t orders)
      : dag_(dag),
        f_(field),
        n_(n),
        W_(n + 1),
        N_(orders),
        data_(dag.nodes().size() * N_ * W_),
        aux_slot_(dag.nodes().size(), -1),
        tmp_(W_),
        tmp2_(W_) {
    std::size_t slots = 0;
    for (std::size_t i = 0; i < dag.nodes().size(); ++i)
      if (needs_aux(dag.nodes()[i].op)) aux_slot_[i] = static_cast<long>(slots++);
    aux_.resize(slots * N_ * W_);
  }

  // Runs the recurrences for orders 0..N-1 with x0 and the symbol values given; false when
  // the point is not regular. `field[i]` is the DAG node of x_i'.
  bool run(const std::vector<T>& x0, const std::vector<T>& symbols, const std::vector<int>& field,
           const Budget* budget) {
    x0_ = &x0;
    symbols_ = &symbols;
    field_ = &field;
    for (std::size_t k = 0; k < N_; ++k) {
      for (std::size_t i = 0; i < dag_.nodes().size(); ++i)
        if (!coefficient(i, k)) return false;
      if (budget) budget->check();
    }
    return true;
  }
  // d(Taylor coefficient k of node)/d x0_j.
  const T& gradient(int node, std::size_t k, std::size_t j) const {
    return data_[(static_cast<std::size_t>(node) * N_ + k) * W_ + 1 + j];
  }

 private:
  static bool needs_aux(Op op) {
    return op == Op::sin || op == Op::cos || op == Op::tan || op == Op::tanh || op == Op::atan;
  }
  T* at(std::size_t node, std::size_t k) { return &data_[(node * N_ + k) * W_]; }
  T* aux(std::size_t node, std::size_t k) {
    return &aux_[(static_cast<std::size_t>(aux_slot_[node]) * N_ + k) * W_];
  }

  void zero(T* r) {
    for (std::size_t c = 0; c < W_; ++c) f_.zero(r[c]);
  }
  // r += a * b (duals)
  void mul_add(T* r, const T* a, const T* b) {
    f_.addmul(r[0], a[0], b[0]);
    for (std::size_t c = 1; c < W_; ++c) {
      f_.addmul(r[c], a[0], b[c]);
      f_.addmul(r[c], a[c], b[0]);
    }
  }
  // r = s * a (scalar s)
  void scale(T* r, const T* a, const T& s) {
    for (std::size_t c = 0; c < W_; ++c) f_.mul(r[c], a[c], s);
  }
  void scale_si(T* r, const T* a, long s) {
    T t;
    f_.set_si(t, s);
    scale(r, a, t);
  }
  // r += s * a
  void add_scaled(T* r, const T* a, const T& s) {
    for (std::size_t c = 0; c < W_; ++c) f_.addmul(r[c], a[c], s);
  }
  // r = a / b (duals)
  bool div(T* r, const T* a, const T* b) {
    T ib;
    if (!f_.inv(ib, b[0])) return false;
    f_.mul(r[0], a[0], ib);
    for (std::size_t c = 1; c < W_; ++c) {
      T t;
      f_.mul(t, r[0], b[c]);
      f_.sub(t, a[c], t);
      f_.mul(r[c], t, ib);
    }
    return true;
  }
  // r = (F(a0), F'(a0) a0')
  void chain(T* r, const T& fv, const T& dfv, const T* a) {
    f_.set(r[0], fv);
    for (std::size_t c = 1; c < W_; ++c) f_.mul(r[c], dfv, a[c]);
  }
  // tmp_ = sum_{j=1..k} w_j a_j y_{k-j}, a_j the coefficients of node a, y(j) a coefficient
  // pointer, w(w_j, j) the weight.
  template <class Y, class Wt>
  void weighted(std::size_t a, std::size_t k, const Y& y, const Wt& w) {
    T* s = tmp_.data();
    zero(s);
    if (scaled_.size() < k * W_) scaled_.resize(k * W_);
    for (std::size_t j = 1; j <= k; ++j) {  // scaled_[j-1] = w_j a_j
      T wj;
      w(wj, j);
      scale(&scaled_[(j - 1) * W_], at(a, j), wj);
    }
    f_.convolve(s, scaled_.data(), static_cast<long>(W_), y(k - 1), -static_cast<long>(W_), k, W_);
  }
  bool coefficient(std::size_t i, std::size_t k);
  bool trig_coefficient(std::size_t i, std::size_t k, const Node& nd, const T& inv_k);
  bool log_atan_coefficient(std::size_t i, std::size_t k, const Node& nd, const T& inv_k);
  bool leading(std::size_t i);

  const Program& dag_;
  const F& f_;
  std::size_t n_, W_, N_;
  std::vector<T> data_, aux_;
  std::vector<long> aux_slot_;
  std::vector<T> tmp_, tmp2_, scaled_;
  const std::vector<T>* x0_ = nullptr;
  const std::vector<T>* symbols_ = nullptr;
  const std::vector<int>* field_ = nullptr;
};

// Order 0: values and gradients at x0.
template <class F>
bool Taylor<F>::leading(std::size_t i) {
  const Node& nd = dag_.nodes()[i];
  T* r = at(i, 0);
  zero(r);
  switch (nd.op) {
    case Op::constant:
      return f_.set_rational(r[0], nd.value);
    case Op::state:
      f_.set(r[0], (*x0_)[static_cast<std::size_t>(nd.index)]);
      f_.set_si(r[1 + static_cast<std::size_t>(nd.index)], 1);
      return true;
    case Op::symbol:
      f_.set(r[0], (*symbols_)[static_cast<std::size_t>(nd.index)]);
      return true;
    case Op::add: {
      const T *a = at(nd.a, 0), *b = at(nd.b, 0);
      for (std::size_t c = 0; c < W_; ++c) f_.add(r[c], a[c], b[c]);
      return true;
    }
    case Op::mul:
      mul_add(r, at(nd.a, 0), at(nd.b, 0));
      return true;
    case Op::inv: {
      std::vector<T> one(W_);
      zero(one.data());
      f_.set_si(one[0], 1);
      return div(r, one.data(), at(nd.a, 0));
    }
    case Op::pow_rat: {
      T fv, dfv;
      if (!f_.pow_rat(fv, dfv, at(nd.a, 0)[0], nd.value)) return false;
      chain(r, fv, dfv, at(nd.a, 0));
      return true;
    }
    default: {
      T fv, dfv;
      const T* a = at(nd.a, 0);
      if (!f_.function(nd.op, fv, dfv, a[0])) return false;
      chain(r, fv, dfv, a);
      if (!needs_aux(nd.op)) return true;
      T* x = aux(i, 0);
      zero(x);
      if (nd.op == Op::sin || nd.op == Op::cos) {  // the companion: cos for sin, -(-sin)...
        T g, dg;
        f_.function(nd.op == Op::sin ? Op::cos : Op::sin, g, dg, a[0]);
        chain(x, g, dg, a);
      } else if (nd.op == Op::atan) {  // b = 1 + a^2
        f_.set_si(x[0], 1);
        mul_add(x, a, a);
      } else {  // q = 1 -+ c^2 (tanh, tan)
        f_.set_si(x[0], 1);
        std::vector<T> sq(W_);
        zero(sq.data());
        mul_add(sq.data(), r, r);
        for (std::size_t c = 0; c < W_; ++c)
          nd.op == Op::tanh ? f_.sub(x[c], x[c], sq[c]) : f_.add(x[c], x[c], sq[c]);
      }
      return true;
    }
  }
}

template <class F>
bool Taylor<F>::coefficient(std::size_t i, std::size_t k) {
  if (k == 0) return leading(i);
  const Node& nd = dag_.nodes()[i];
  T* r = at(i, k);
  zero(r);
  T* s = tmp_.data();
  const auto a = static_cast<std::size_t>(nd.a);
  T inv_k;
  f_.set_si(inv_k, static_cast<long>(k));
  if (!f_.inv(inv_k, inv_k)) return false;
  auto weight_j = [&](T& w, std::size_t j) { f_.set_si(w, static_cast<long>(j)); };
  auto self = [&](std::size_t j) { return at(i, j); };
  switch (nd.op) {
    case Op::constant:
    case Op::symbol:
      return true;
    case Op::state: {
      const T* fk =
          at(static_cast<std::size_t>((*field_)[static_cast<std::size_t>(nd.index)]), k - 1);
      scale(r, fk, inv_k);
      return true;
    }
    case Op::add: {
      const T *x = at(a, k), *b = at(nd.b, k);
      for (std::size_t c = 0; c < W_; ++c) f_.add(r[c], x[c], b[c]);
      return true;
    }
    case Op::mul:
      f_.convolve(r, at(a, 0), static_cast<long>(W_), at(nd.b, k), -static_cast<long>(W_), k + 1,
                  W_);
      return true;
    case Op::inv:  // a c = 1: c_k = -(sum_{j>=1} a_j c_{k-j}) / a_0
      weighted(a, k, self, [&](T& w, std::size_t) { f_.set_si(w, -1); });
      return div(r, s, at(a, 0));
    case Op::pow_rat:  // k a_0 c_k = sum_j (q j - (k - j)) a_j c_{k-j}
      weighted(a, k, self, [&](T& w, std::size_t j) {
        const numeric c = nd.value * static_cast<long>(j) - static_cast<long>(k - j);
        f_.set_rational(w, c);
      });
      if (!div(r, s, at(a, 0))) return false;
      scale(r, r, inv_k);
      return true;
    case Op::exp:  // c' = a' c
      weighted(a, k, self, weight_j);
      scale(r, s, inv_k);
      return true;
    case Op::sin:
    case Op::cos:
    case Op::tan:
    case Op::tanh:
      return trig_coefficient(i, k, nd, inv_k);
    case Op::log:
    case Op::atan:
      return log_atan_coefficient(i, k, nd, inv_k);
  }
  return false;
}

// sin/cos: s' = a' c, c' = -a' s, the node holds one, aux the other. tan/tanh: c' = a' q with
// q = 1 +- c^2 in aux.
template <class F>
bool Taylor<F>::trig_coefficient(std::size_t i, std::size_t k, const Node& nd, const T& inv_k) {
  const auto a = static_cast<std::size_t>(nd.a);
  T* r = at(i, k);
  T* s = tmp_.data();
  auto weight_j = [&](T& w, std::size_t j) { f_.set_si(w, static_cast<long>(j)); };
  auto self = [&](std::size_t j) { return at(i, j); };
  auto companion = [&](std::size_t j) { return aux(i, j); };
  weighted(a, k, companion, weight_j);
  scale(r, s, inv_k);
  T* x = aux(i, k);
  if (nd.op == Op::sin || nd.op == Op::cos) {
    const long sign_self = nd.op == Op::sin ? 1 : -1;
    scale_si(r, r, sign_self);
    weighted(a, k, self, weight_j);
    scale(x, s, inv_k);
    scale_si(x, x, -sign_self);
    return true;
  }
  zero(x);
  for (std::size_t j = 0; j <= k; ++j) mul_add(x, at(i, j), at(i, k - j));
  if (nd.op == Op::tanh) scale_si(x, x, -1);
  return true;
}

// b c' = a' with b = a (log) or 1 + a^2 (atan, held in aux):
// k b_0 c_k = k a_k - sum_{j=1..k-1} (k - j) b_j c_{k-j}
template <class F>
bool Taylor<F>::log_atan_coefficient(std::size_t i, std::size_t k, const Node& nd, const T& inv_k) {
  const auto a = static_cast<std::size_t>(nd.a);
  T* r = at(i, k);
  T* s = tmp_.data();
  auto B = [&](std::size_t j) { return nd.op == Op::log ? at(a, j) : aux(i, j); };
  if (nd.op == Op::atan) {
    T* x = aux(i, k);
    zero(x);
    for (std::size_t j = 0; j <= k; ++j) mul_add(x, at(a, j), at(a, k - j));
  }
  zero(s);
  for (std::size_t j = 1; j < k; ++j) {
    zero(tmp2_.data());
    mul_add(tmp2_.data(), B(j), at(i, k - j));
    T w;
    f_.set_si(w, -static_cast<long>(k - j));
    add_scaled(s, tmp2_.data(), w);
  }
  T kk;
  f_.set_si(kk, static_cast<long>(k));
  add_scaled(s, at(a, k), kk);
  if (!div(r, s, B(0))) return false;
  scale(r, r, inv_k);
  return true;
}

// ---------------------------------------------------------------------------------------------
// Rows of O at a point and their rank: rows are added in k-major order; a row that does not
// raise the rank stops its output (observability indices).

struct PointRank {
  std::size_t rank = 0;
  std::vector<std::size_t> indices, selected;
};

template <class F>
PointRank row_rank(const F& f, const Taylor<F>& t, const std::vector<int>& outputs, std::size_t n) {
  using T = typename F::T;
  const std::size_t p = outputs.size();
  PointRank pr;
  pr.indices.assign(p, 0);
  std::vector<bool> stopped(p, false);
  std::vector<std::vector<T>> basis;  // reduced rows
  std::vector<std::size_t> pivots;
  for (std::size_t k = 0, row = 0; k < n; ++k)
    for (std::size_t i = 0; i < p; ++i, ++row) {
      if (stopped[i]) continue;
      std::vector<T> v(n);
      for (std::size_t j = 0; j < n; ++j) f.set(v[j], t.gradient(outputs[i], k, j));
      for (std::size_t b = 0; b < basis.size(); ++b) {  // v -= (v_pivot / b_pivot) b
        T factor;
        f.inv(factor, basis[b][pivots[b]]);
        f.mul(factor, factor, v[pivots[b]]);
        for (std::size_t j = 0; j < n; ++j) {
          T u;
          f.mul(u, factor, basis[b][j]);
          f.sub(v[j], v[j], u);
        }
      }
      std::optional<std::size_t> piv;
      for (std::size_t j = 0; j < n && !piv; ++j)
        if (f.nonzero(v[j])) piv = j;
      if (!piv) {
        stopped[i] = true;
        continue;
      }
      basis.push_back(std::move(v));
      pivots.push_back(*piv);
      pr.selected.push_back(row);
      ++pr.indices[i];
    }
  pr.rank = basis.size();
  return pr;
}

std::uint64_t splitmix(std::uint64_t& s) {
  std::uint64_t z = (s += 0x9e3779b97f4a7c15ULL);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

struct Problem {
  const Model& m;
  Program dag;
  std::vector<int> drift, full, outputs;  // roots
  Problem(const Model& model, const Symbols& symbols)
      : m(model), dag(model.states, symbols, model) {
    for (std::size_t i = 0; i < m.n(); ++i) {
      drift.push_back(dag.add(m.f[i]));
      full.push_back(m.g[i].is_zero() ? drift.back() : dag.add(m.f[i] + m.g[i]));
    }
    for (const auto& h : m.h) outputs.push_back(dag.add(h));
  }
};

// Rank at one point: drift (inputs 0) and with the inputs at their sampled values.
template <class F>
std::optional<std::pair<PointRank, PointRank>> rank_at(const Problem& pb, const F& f,
                                                       const std::vector<typename F::T>& x0,
                                                       std::vector<typename F::T> symbols,
                                                       std::size_t inputs_from,
                                                       const Budget* budget) {
  const std::size_t n = pb.m.n();
  Taylor<F> t(pb.dag, f, n, n);
  if (!t.run(x0, symbols, pb.full, budget)) return std::nullopt;
  const PointRank with_inputs = row_rank(f, t, pb.outputs, n);
  if (pb.full == pb.drift) return std::make_pair(with_inputs, with_inputs);
  for (std::size_t s = inputs_from; s < symbols.size(); ++s) f.zero(symbols[s]);
  if (!t.run(x0, symbols, pb.drift, budget)) return std::nullopt;
  return std::make_pair(row_rank(f, t, pb.outputs, n), with_inputs);
}

// Full rank is proven by one point: more points cannot change it.
bool proven(const JetsRank& r) {
  return r.points > 0 && r.rank == r.n && r.rank_inputs == r.n;
}

void keep_best(JetsRank& out, const std::pair<PointRank, PointRank>& r) {
  if (out.points == 0 || r.first.rank > out.rank) {
    out.rank = r.first.rank;
    out.indices = r.first.indices;
    out.selected = r.first.selected;
  }
  out.rank_inputs = std::max(out.rank_inputs, r.second.rank);
  ++out.points;
}

void modular_ranks(const Problem& pb, std::size_t inputs_from, const JetsOptions& opt,
                   const Budget* budget, JetsRank& out) {
  std::uint64_t state = opt.seed;
  mp_limb_t prime = UWORD(1) << 62;
  const std::size_t n = pb.m.n();
  const std::size_t symbol_count = inputs_from + pb.m.m();
  for (int attempt = 0; attempt < 8 * opt.points && out.points < opt.points && !proven(out);
       ++attempt) {
    prime = n_nextprime(prime, 1);
    const ModField f(prime);
    std::vector<mp_limb_t> x0(n), symbols(symbol_count);
    for (auto& v : x0) v = splitmix(state) % prime;
    for (auto& v : symbols) v = splitmix(state) % prime;
    const auto r = rank_at(pb, f, x0, symbols, inputs_from, budget);
    if (!r) continue;
    keep_best(out, *r);
    out.primes.push_back(prime);
  }
}

// Ball arithmetic at one point: the precision is doubled from `start` until two precisions
// agree, or (settled) one run at `start`: a rank from certified pivots is a proven lower
// bound whatever the precision, and the doubling only guards the claim that it is not higher.
std::optional<std::pair<PointRank, PointRank>> ball_rank_at(
    const Problem& pb, const GiNaC::exmap& point, const Symbols& symbols, std::size_t inputs_from,
    const JetsOptions& opt, const Budget* budget, long start, bool settled, long& prec_used) {
  std::optional<std::pair<PointRank, PointRank>> last;
  for (long prec = start; prec <= opt.max_precision_bits; prec *= 2) {
    BallField f{prec};
    std::vector<Ball> x0(pb.m.n()), vals(symbols.size());
    for (std::size_t i = 0; i < x0.size(); ++i)
      f.set_rational(x0[i], GiNaC::ex_to<numeric>(point.at(pb.m.states[i])));
    for (std::size_t i = 0; i < vals.size(); ++i)
      f.set_rational(vals[i], GiNaC::ex_to<numeric>(point.at(symbols[i])));
    auto r = rank_at(pb, f, x0, vals, inputs_from, budget);
    const std::size_t n = pb.m.n();
    if (r && r->first.rank == n && r->second.rank == n) {  // certified pivots: a proof
      prec_used = prec;
      return r;
    }
    if (r && last && r->first.rank == last->first.rank && r->second.rank == last->second.rank) {
      prec_used = prec;
      return r;
    }
    if (r) last = r;
    if (r && settled) {
      prec_used = prec;
      return r;
    }
  }
  if (last) prec_used = opt.max_precision_bits;
  return last;
}

void ball_ranks(const Problem& pb, const Symbols& symbols, std::size_t inputs_from,
                const JetsOptions& opt, const Budget* budget, JetsRank& out) {
  Symbols sampled(pb.m.states);
  sampled.insert(sampled.end(), symbols.begin(), symbols.end());
  const auto points = sample_points(sampled, pb.m.sample_boxes(), 8 * opt.points, opt.seed);
  for (const auto& pt : points) {
    if (out.points >= opt.points || proven(out)) break;
    long prec = 0;
    const bool settled = out.points > 0;
    const auto r = ball_rank_at(pb, pt, symbols, inputs_from, opt, budget,
                                settled ? out.precision_bits : opt.precision_bits, settled, prec);
    if (!r) continue;
    keep_best(out, *r);
    out.precision_bits = std::max(out.precision_bits, prec);
  }
}

std::string method_text(const JetsRank& r) {
  if (r.arithmetic == JetsArithmetic::modular) {
    std::string bound = r.rank == r.n ? "full rank, proven by a nonzero minor modulo p"
                                      : fmt::format(
                                            "P(rank under-estimated) <= {:.2g} "
                                            "(Schwartz-Zippel, minor degree <= {}, p ~ 2^62)",
                                            r.error_bound, r.degree_bound);
    return fmt::format("Taylor jets at {} random point{} modulo 62-bit primes; {}", r.points,
                       r.points == 1 ? "" : "s", bound);
  }
  const std::string pts = fmt::format("{} random point{}", r.points, r.points == 1 ? "" : "s");
  if (r.rank == r.n)
    return fmt::format(
        "Taylor jets in {}-bit ball arithmetic at {} of the domain; full rank, "
        "proven by certified nonzero pivots",
        r.precision_bits, pts);
  return fmt::format(
      "Taylor jets in {}-bit ball arithmetic at {} of the domain; rank >= {} proven by certified "
      "nonzero pivots, rank <= {} rests on the {} (no probability bound)",
      r.precision_bits, pts, r.rank, r.rank, pts);
}

}  // namespace

JetsRank jets_rank(const Model& m, const JetsOptions& opt, const Budget* budget) {
  // Symbols: free parameters first, then the inputs (zeroed for the drift rank).
  Symbols symbols = m.free_params();
  const std::size_t inputs_from = symbols.size();
  symbols.insert(symbols.end(), m.inputs.begin(), m.inputs.end());
  const Problem pb(m, symbols);
  JetsRank out;
  out.n = m.n();
  out.p = m.p();
  out.dag_nodes = pb.dag.nodes().size();
  if (pb.dag.rational() && !opt.force_ball) {
    out.arithmetic = JetsArithmetic::modular;
    modular_ranks(pb, inputs_from, opt, budget, out);
    const auto deg = degrees(pb.dag);
    out.degree_bound = minor_degree_bound(deg, pb.drift, pb.outputs, m.n());
    out.degree_bound_inputs = minor_degree_bound(deg, pb.full, pb.outputs, m.n());
    auto bound = [&](unsigned long d, std::size_t rank) {
      if (rank == m.n()) return 0.0;
      double b = 1;
      for (auto p : out.primes)
        b *= std::min(1.0, 2.0 * static_cast<double>(d) / static_cast<double>(p));
      return b;
    };
    out.error_bound = bound(out.degree_bound, out.rank);
    out.error_bound_inputs = bound(out.degree_bound_inputs, out.rank_inputs);
  } else {
    out.arithmetic = JetsArithmetic::ball;
    ball_ranks(pb, symbols, inputs_from, opt, budget, out);
  }
  if (out.points == 0)
    throw UserError(SourceLoc{m.file, 0, 0},
                    "the jets rank found no regular point (every sampled point hit a pole or left "
                    "the domain of a function); declare a 'domain' where the model is defined");
  out.method = method_text(out);
  return out;
}

}  // namespace obsynth
