#include "symbolic/poly.hpp"

#include <algorithm>
#include <cstring>
#include <string>

#include "symbolic/symbolic.hpp"

namespace obsynth {

using GiNaC::ex;
using GiNaC::is_a;

namespace {

cln::cl_RA to_rational(const GiNaC::numeric& v) {
  return cln::the<cln::cl_RA>(v.to_cl_N());
}

// k as a rational without CLN's inline cl_RA(int), which left-shifts negative values.
cln::cl_RA small_rational(int k) {
  return k < 0 ? -cln::cl_RA(-k) : cln::cl_RA(k);
}

std::int8_t checked_exponent(int s) {
  if (s < -128 || s > 127) throw PolyOverflow{};
  return static_cast<std::int8_t>(s);
}

// acc += c * m * q (q a polynomial).
void accumulate(Poly& acc, const Monomial& m, const cln::cl_RA& c, const Poly& q) {
  for (const auto& [qm, qc] : q.terms) {
    Monomial r;
    for (std::size_t i = 0; i < kMaxPolyVariables; ++i)
      r.e[i] = checked_exponent(int{m.e[i]} + qm.e[i]);
    const cln::cl_RA v = c * qc;
    auto [it, inserted] = acc.terms.try_emplace(r, v);
    if (!inserted) {
      it->second = it->second + v;
      if (cln::zerop(it->second)) acc.terms.erase(it);
    }
  }
}

// acc += a * b, iterating over the shorter operand (field components are usually short).
void accumulate_product(Poly& acc, const Poly& a, const Poly& b) {
  const Poly& small = a.terms.size() <= b.terms.size() ? a : b;
  const Poly& large = &small == &a ? b : a;
  for (const auto& [m, c] : small.terms) accumulate(acc, m, c, large);
}

void add_term(Poly& acc, const Monomial& m, const cln::cl_RA& c) {
  if (cln::zerop(c)) return;
  auto [it, inserted] = acc.terms.try_emplace(m, c);
  if (!inserted) {
    it->second = it->second + c;
    if (cln::zerop(it->second)) acc.terms.erase(it);
  }
}

Poly constant(const cln::cl_RA& c) {
  Poly p;
  add_term(p, Monomial{}, c);
  return p;
}

Poly monomial(std::size_t v, int power, const cln::cl_RA& c = 1) {
  Poly p;
  Monomial m;
  m.e[v] = checked_exponent(power);
  add_term(p, m, c);
  return p;
}

Poly variable(std::size_t v) {
  return monomial(v, 1);
}

bool is_function(const ex& e, const char* name) {
  return is_a<GiNaC::function>(e) && GiNaC::ex_to<GiNaC::function>(e).get_name() == name;
}

// cos(k a), sin(k a) for k >= 0 as polynomials in c = cos(a), s = sin(a):
// (c + i s)^k = sum_j C(k, j) c^(k-j) (i s)^j.
std::pair<Poly, Poly> de_moivre(std::size_t s_var, std::size_t c_var, int k) {
  Poly cos_k, sin_k;
  cln::cl_RA binom = 1;
  for (int j = 0; j <= k; ++j) {
    Monomial m;
    m.e[c_var] = checked_exponent(k - j);
    m.e[s_var] = checked_exponent(j);
    const cln::cl_RA c = (j / 2) % 2 == 0 ? binom : -binom;  // i^j = ±1 or ±i
    add_term(j % 2 == 0 ? cos_k : sin_k, m, c);
    binom = binom * small_rational(k - j) / small_rational(j + 1);
  }
  return {cos_k, sin_k};
}

Poly negated(Poly p) {
  for (auto& [m, c] : p.terms) c = -c;
  return p;
}

}  // namespace

std::size_t MonomialHash::operator()(const Monomial& m) const noexcept {
  std::uint64_t words[kMaxPolyVariables / 8];
  static_assert(sizeof(words) == sizeof(m.e));
  std::memcpy(words, m.e.data(), sizeof(words));
  std::uint64_t h = 0x9e3779b97f4a7c15ULL;
  for (std::uint64_t w : words) {
    h ^= w + 0x9e3779b97f4a7c15ULL + (h << 6) + (h >> 2);
    h *= 0xff51afd7ed558ccdULL;
  }
  return static_cast<std::size_t>(h ^ (h >> 33));
}

std::size_t Poly::node_estimate() const {
  std::size_t n = 1;
  for (const auto& [m, c] : terms) {
    n += 2;  // the product and its coefficient
    for (std::int8_t e : m.e) n += e == 0 ? 0 : (e == 1 ? 1 : 3);
  }
  return n;
}

std::optional<std::size_t> PolyRing::find(const ex& v) const {
  for (std::size_t i = 0; i < vars_.size(); ++i)
    if (vars_[i].value.is_equal(v)) return i;
  return std::nullopt;
}

std::optional<std::size_t> PolyRing::find_family(Kind kind, const ex& key) const {
  for (std::size_t i = 0; i < families_.size(); ++i)
    if (families_[i].kind == kind && families_[i].key.is_equal(key)) return i;
  return std::nullopt;
}

void PolyRing::note_family(Kind kind, const ex& key, const GiNaC::numeric& multiple) {
  if (const auto f = find_family(kind, key)) {
    families_[*f].unit = rational_gcd(families_[*f].unit, multiple);
    return;
  }
  families_.push_back({kind, key, GiNaC::abs(multiple)});
  pending_.push_back({families_.size() - 1, 0});
}

bool PolyRing::register_atoms(const ex& e) {
  if (is_a<GiNaC::numeric>(e)) return GiNaC::ex_to<GiNaC::numeric>(e).is_rational();
  if (is_a<GiNaC::symbol>(e) || is_a<GiNaC::constant>(e)) {
    if (!find(e)) vars_.push_back({e, Kind::symbol, 0});
    return true;
  }
  if (is_a<GiNaC::add>(e) || is_a<GiNaC::mul>(e)) {
    for (std::size_t i = 0; i < e.nops(); ++i)
      if (!register_atoms(e.op(i))) return false;
    return true;
  }
  if (is_a<GiNaC::power>(e)) {
    const ex q = e.op(1);  // negative powers are checked by convert (exp bases only)
    if (!is_a<GiNaC::numeric>(q) || !GiNaC::ex_to<GiNaC::numeric>(q).is_integer()) return false;
    return register_atoms(e.op(0));
  }
  return register_function(e);
}

bool PolyRing::register_function(const ex& e) {
  if (!is_a<GiNaC::function>(e) || e.nops() != 1) return false;
  const ex arg = e.op(0);
  if (!register_atoms(arg)) return false;  // inner atoms first: their derivatives are built first
  if (is_function(e, "exp")) {
    const auto terms = argument_terms(arg);
    if (!terms) return false;
    for (const ArgumentTerm& t : *terms) note_family(Kind::exp, t.monomial, t.coeff);
    return true;
  }
  if (!is_function(e, "sin") && !is_function(e, "cos") && !is_function(e, "tanh")) return false;
  const auto d = argument_direction(arg);
  if (!d) return false;
  if (is_function(e, "tanh")) {  // no multiple-angle reduction: tanh(2a) is rational in tanh(a)
    const ex key = d->multiple.is_negative() ? ex(-d->multiple * d->key) : arg;
    for (const auto& p : pending_)
      if (!p.family && p.tanh_arg.is_equal(key)) return true;
    pending_.push_back({std::nullopt, key});
    return true;
  }
  note_family(Kind::sin, d->key, d->multiple);
  return true;
}

// Bases in order of discovery; each atom's argument only uses atoms created before it.
// False when GiNaC evaluates a base to something else (sin(Pi/2) = 1): no canonical atom.
bool PolyRing::create_bases() {
  auto add = [&](const ex& value, Kind kind, const ex& arg, const char* name) {
    vars_.push_back({value, kind, arg});
    return is_function(value, name) && value.op(0).is_equal(arg);
  };
  for (const Pending& p : pending_) {
    if (!p.family) {
      if (!add(GiNaC::tanh(p.tanh_arg), Kind::tanh, p.tanh_arg, "tanh")) return false;
      continue;
    }
    Family& f = families_[*p.family];
    const ex arg = GiNaC::expand(f.unit * f.key);
    f.var = vars_.size();
    const bool ok = f.kind == Kind::exp ? add(GiNaC::exp(arg), Kind::exp, arg, "exp")
                                        : add(GiNaC::sin(arg), Kind::sin, arg, "sin") &&
                                              add(GiNaC::cos(arg), Kind::cos, arg, "cos");
    if (!ok) return false;
  }
  return true;
}

bool PolyRing::build_derivatives() {
  derivs_.assign(vars_.size(), std::vector<Poly>(states_));
  var_growth_.assign(vars_.size(), Growth::constant);
  for (std::size_t v = 0; v < states_; ++v) var_growth_[v] = Growth::unbounded;
  for (std::size_t v = states_; v < vars_.size(); ++v) {
    const Variable& var = vars_[v];
    if (var.kind == Kind::symbol) continue;
    const auto arg = convert(var.arg);
    if (!arg) return false;
    Poly outer;  // F'(arg) in the ring
    switch (var.kind) {
      case Kind::sin:
        outer = variable(v + 1);
        break;
      case Kind::cos:
        outer = negated(variable(v - 1));
        break;
      case Kind::exp:
        outer = variable(v);
        break;
      case Kind::tanh:  // 1 - tanh^2
        outer = monomial(v, 2, minus_one());
        add_term(outer, Monomial{}, 1);
        break;
      default:
        return false;
    }
    bool depends = false;
    for (std::size_t j = 0; j < states_; ++j) {
      const Poly da = derivative(*arg, j);  // inner atoms already have their derivatives
      if (!da.is_zero()) derivs_[v][j] = product(outer, da);
      depends |= !da.is_zero();
    }
    if (depends) var_growth_[v] = var.kind == Kind::exp ? Growth::unbounded : Growth::bounded;
  }
  return true;
}

std::optional<PolyRing> PolyRing::for_expressions(const std::vector<ex>& exprs,
                                                  const std::vector<GiNaC::symbol>& x) {
  PolyRing ring;
  ring.states_ = x.size();
  for (const auto& s : x) ring.vars_.push_back({s, Kind::state, 0});
  try {
    for (const auto& e : exprs)
      if (!ring.register_atoms(e)) return std::nullopt;
    if (!ring.create_bases() || ring.vars_.size() > kMaxPolyVariables) return std::nullopt;
    if (!ring.build_derivatives()) return std::nullopt;
    // Every expression converts (exponents in range), so callers may dereference from_ex.
    for (const auto& e : exprs)
      if (!ring.convert(e)) return std::nullopt;
  } catch (const PolyOverflow&) {
    return std::nullopt;
  }
  return ring;
}

std::optional<ex> PolyRing::canonical_form(const ex& e) {
  PolyRing ring;
  try {
    if (!ring.register_atoms(e) || !ring.create_bases() || ring.vars_.size() > kMaxPolyVariables)
      return std::nullopt;  // (no derivatives: the ring only converts)
    const auto p = ring.convert(e);
    if (!p) return std::nullopt;
    return ring.to_ex(*p);
  } catch (const PolyOverflow&) {
    return std::nullopt;
  }
}

std::optional<Poly> PolyRing::convert(const ex& e) const {
  if (is_a<GiNaC::numeric>(e)) {
    const auto& v = GiNaC::ex_to<GiNaC::numeric>(e);
    if (!v.is_rational()) return std::nullopt;
    return constant(to_rational(v));
  }
  if (is_a<GiNaC::add>(e)) {
    Poly acc;
    for (std::size_t i = 0; i < e.nops(); ++i) {
      const auto t = convert(e.op(i));
      if (!t) return std::nullopt;
      add_to(acc, *t);
    }
    return acc;
  }
  if (is_a<GiNaC::mul>(e)) {
    Poly acc = constant(1);
    for (std::size_t i = 0; i < e.nops(); ++i) {
      const auto t = convert(e.op(i));
      if (!t) return std::nullopt;
      acc = product(acc, *t);
    }
    return acc;
  }
  if (is_a<GiNaC::power>(e)) return convert_power(e);
  if (is_a<GiNaC::function>(e)) return convert_function(e);
  const auto v = find(e);
  if (!v || (vars_[*v].kind != Kind::symbol && vars_[*v].kind != Kind::state)) return std::nullopt;
  return variable(*v);
}

// Integer powers; negative ones only of a Laurent monomial (a constant times exp bases).
std::optional<Poly> PolyRing::convert_power(const ex& e) const {
  const ex q = e.op(1);
  if (!is_a<GiNaC::numeric>(q) || !GiNaC::ex_to<GiNaC::numeric>(q).is_integer() ||
      GiNaC::abs(GiNaC::ex_to<GiNaC::numeric>(q)) > 0xFF)
    return std::nullopt;
  auto base = convert(e.op(0));
  if (!base) return std::nullopt;
  long k = GiNaC::ex_to<GiNaC::numeric>(q).to_long();
  if (k < 0) {
    if (base->terms.size() != 1) return std::nullopt;
    const auto& [m, c] = *base->terms.begin();
    Monomial inv;
    for (std::size_t v = 0; v < vars_.size(); ++v) {
      if (m.e[v] != 0 && vars_[v].kind != Kind::exp) return std::nullopt;
      inv.e[v] = checked_exponent(-int{m.e[v]});
    }
    Poly p;
    add_term(p, inv, cln::recip(c));
    base = p;
    k = -k;
  }
  Poly acc = constant(1), sq = *base;
  for (; k > 0; k >>= 1) {
    if (k & 1) acc = product(acc, sq);
    if (k > 1) sq = product(sq, sq);
  }
  return acc;
}

std::optional<Poly> PolyRing::convert_function(const ex& e) const {
  if (e.nops() != 1) return std::nullopt;
  const ex arg = e.op(0);
  auto multiple_of = [](const Family& f, const GiNaC::numeric& c) -> std::optional<int> {
    const GiNaC::numeric k = c / f.unit;
    if (!k.is_integer() || GiNaC::abs(k) > 127) return std::nullopt;
    return static_cast<int>(k.to_long());
  };
  if (is_function(e, "exp")) {
    const auto terms = argument_terms(arg);
    if (!terms) return std::nullopt;
    Monomial m;
    for (const ArgumentTerm& t : *terms) {
      const auto f = find_family(Kind::exp, t.monomial);
      if (!f) return std::nullopt;
      const auto k = multiple_of(families_[*f], t.coeff);
      if (!k) return std::nullopt;
      const std::size_t v = families_[*f].var;
      m.e[v] = checked_exponent(int{m.e[v]} + *k);
    }
    Poly p;
    add_term(p, m, 1);
    return p;
  }
  const auto d = argument_direction(arg);
  if (!d) return std::nullopt;
  if (is_function(e, "tanh")) {
    const bool flip = d->multiple.is_negative();
    const auto v = find(GiNaC::tanh(flip ? ex(-d->multiple * d->key) : arg));
    if (!v || vars_[*v].kind != Kind::tanh) return std::nullopt;
    return flip ? negated(variable(*v)) : variable(*v);
  }
  if (!is_function(e, "sin") && !is_function(e, "cos")) return std::nullopt;
  const auto f = find_family(Kind::sin, d->key);
  if (!f) return std::nullopt;
  const auto k = multiple_of(families_[*f], d->multiple);
  if (!k) return std::nullopt;
  const std::size_t s = families_[*f].var;
  auto [cos_k, sin_k] = de_moivre(s, s + 1, std::abs(*k));
  if (is_function(e, "cos")) return cos_k;
  return *k < 0 ? negated(sin_k) : sin_k;
}

std::optional<Poly> PolyRing::from_ex(const ex& e) const {
  try {
    return convert(e);
  } catch (const PolyOverflow&) {
    return std::nullopt;
  }
}

ex PolyRing::to_ex(const Poly& p) const {
  // Terms in a fixed order, so that GiNaC builds the same tree on every run.
  std::vector<const std::pair<const Monomial, cln::cl_RA>*> order;
  order.reserve(p.terms.size());
  for (const auto& t : p.terms) order.push_back(&t);
  std::sort(order.begin(), order.end(), [](auto* a, auto* b) { return a->first.e < b->first.e; });
  GiNaC::exvector terms;
  terms.reserve(order.size());
  for (const auto* t : order) {
    GiNaC::exvector factors;
    factors.push_back(GiNaC::numeric(cln::cl_N(t->second)));
    ex exp_arg = 0;  // the exp bases of the term, written as one exp
    for (std::size_t v = 0; v < vars_.size(); ++v) {
      const int k = t->first.e[v];
      if (k == 0) continue;
      if (vars_[v].kind == Kind::exp)
        exp_arg += k * vars_[v].arg;
      else
        factors.push_back(GiNaC::pow(vars_[v].value, k));
    }
    exp_arg = GiNaC::expand(exp_arg);
    if (!exp_arg.is_zero()) factors.push_back(GiNaC::exp(exp_arg));
    terms.push_back(factors.size() == 1 ? factors[0] : ex(GiNaC::mul(factors)));
  }
  if (terms.empty()) return 0;
  if (terms.size() == 1) return terms[0];
  return GiNaC::add(terms);
}

std::optional<std::vector<GiNaC::numeric>> PolyRing::values_at(const GiNaC::exmap& point,
                                                               int digits) const {
  const long saved = GiNaC::Digits;
  GiNaC::Digits = digits;
  std::vector<GiNaC::numeric> out;
  bool ok = true;
  try {
    GiNaC::exmap fpoint;
    for (const auto& [k, v] : point) fpoint[k] = GiNaC::evalf(v);
    for (const auto& var : vars_) {
      const ex v = GiNaC::evalf(var.value.subs(fpoint));
      if (!is_a<GiNaC::numeric>(v) || !GiNaC::ex_to<GiNaC::numeric>(v).is_real()) {
        ok = false;
        break;
      }
      out.push_back(GiNaC::ex_to<GiNaC::numeric>(v));
    }
  } catch (const std::exception&) {
    ok = false;
  }
  GiNaC::Digits = saved;
  if (!ok) return std::nullopt;
  return out;
}

GiNaC::numeric PolyRing::evaluate(const Poly& p, const std::vector<GiNaC::numeric>& values) {
  // In CLN directly: GiNaC's numeric wraps every intermediate in a heap object.
  std::vector<cln::cl_N> v;
  v.reserve(values.size());
  for (const auto& x : values) v.push_back(x.to_cl_N());
  cln::cl_N acc = 0;
  for (const auto& [m, c] : p.terms) {
    cln::cl_N t = c;
    for (std::size_t k = 0; k < v.size(); ++k)
      if (m.e[k] != 0) t = t * (m.e[k] == 1 ? v[k] : cln::expt(v[k], static_cast<long>(m.e[k])));
    acc = acc + t;
  }
  return GiNaC::numeric(acc);
}

Poly PolyRing::derivative(const Poly& p, std::size_t state) const {
  Poly out;
  for (const auto& [m, c] : p.terms) {
    if (m.e[state] > 0) {
      Monomial r = m;
      --r.e[state];
      add_term(out, r, c * small_rational(m.e[state]));
    }
    for (std::size_t v = states_; v < vars_.size(); ++v) {
      if (m.e[v] == 0 || derivs_[v][state].is_zero()) continue;
      Monomial r = m;
      r.e[v] = checked_exponent(m.e[v] - 1);
      accumulate(out, r, c * small_rational(m.e[v]), derivs_[v][state]);
    }
  }
  return out;
}

Growth PolyRing::growth(const Poly& p) const {
  Growth g = Growth::constant;
  for (const auto& [m, c] : p.terms)
    for (std::size_t v = 0; v < vars_.size(); ++v)
      if (m.e[v] != 0 && var_growth_[v] > g) {
        g = var_growth_[v];
        if (g == Growth::unbounded) return g;
      }
  return g;
}

Poly PolyRing::product(const Poly& a, const Poly& b) {
  Poly out;
  accumulate_product(out, a, b);
  return out;
}

void PolyRing::add_to(Poly& acc, const Poly& p, const cln::cl_RA& scale) {
  for (const auto& [m, c] : p.terms) add_term(acc, m, c * scale);
}

Poly PolyRing::dot(const std::vector<Poly>& grad, const std::vector<Poly>& field) {
  Poly out;
  for (std::size_t j = 0; j < grad.size() && j < field.size(); ++j)
    accumulate_product(out, grad[j], field[j]);
  return out;
}

}  // namespace obsynth
