#include "symbolic/poly.hpp"

#include <algorithm>
#include <cstring>

namespace obsynth {

using GiNaC::ex;
using GiNaC::is_a;

namespace {

cln::cl_RA to_rational(const GiNaC::numeric& v) {
  return cln::the<cln::cl_RA>(v.to_cl_N());
}

// acc += c * m * q (q a polynomial).
void accumulate(Poly& acc, const Monomial& m, const cln::cl_RA& c, const Poly& q) {
  for (const auto& [qm, qc] : q.terms) {
    Monomial r;
    for (std::size_t i = 0; i < kMaxPolyVariables; ++i) {
      const std::uint32_t s = std::uint32_t{m.e[i]} + qm.e[i];
      if (s > 0xFF) throw PolyOverflow{};
      r.e[i] = static_cast<std::uint8_t>(s);
    }
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

Poly variable(std::size_t v) {
  Poly p;
  Monomial m;
  m.e[v] = 1;
  p.terms.emplace(m, cln::cl_RA(1));
  return p;
}

bool is_function(const ex& e, const char* name) {
  return is_a<GiNaC::function>(e) && GiNaC::ex_to<GiNaC::function>(e).get_name() == name;
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
    for (std::uint8_t e : m.e) n += e == 0 ? 0 : (e == 1 ? 1 : 3);
  }
  return n;
}

std::optional<std::size_t> PolyRing::find(const ex& v) const {
  for (std::size_t i = 0; i < vars_.size(); ++i)
    if (vars_[i].value.is_equal(v)) return i;
  return std::nullopt;
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
    const ex q = e.op(1);
    if (!is_a<GiNaC::numeric>(q) || !GiNaC::ex_to<GiNaC::numeric>(q).is_nonneg_integer())
      return false;
    return register_atoms(e.op(0));
  }
  if (!is_a<GiNaC::function>(e) || e.nops() != 1) return false;
  const ex arg = e.op(0);
  if (!register_atoms(arg)) return false;  // inner atoms first: their derivatives are built first
  auto add_atom = [&](const ex& atom, Kind kind) {
    if (!find(atom)) vars_.push_back({atom, kind, arg});
  };
  if (is_function(e, "sin") || is_function(e, "cos")) {
    // Each is the other's derivative: both must be atoms of the same argument.
    const ex s = GiNaC::sin(arg), c = GiNaC::cos(arg);
    if (!is_function(s, "sin") || !is_function(c, "cos") || !s.op(0).is_equal(arg) ||
        !c.op(0).is_equal(arg))
      return false;
    add_atom(s, Kind::sin);
    add_atom(c, Kind::cos);
    return true;
  }
  if (is_function(e, "exp")) {
    add_atom(e, Kind::exp);
    return true;
  }
  if (is_function(e, "tanh")) {
    add_atom(e, Kind::tanh);
    return true;
  }
  return false;
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
        outer = variable(*find(GiNaC::cos(var.arg)));
        break;
      case Kind::cos: {
        outer = variable(*find(GiNaC::sin(var.arg)));
        for (auto& [m, c] : outer.terms) c = -c;
        break;
      }
      case Kind::exp:
        outer = variable(v);
        break;
      case Kind::tanh: {
        outer = constant(1);
        Monomial sq;
        sq.e[v] = 2;
        add_term(outer, sq, minus_one());
        break;
      }
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
  for (const auto& e : exprs)
    if (!ring.register_atoms(e)) return std::nullopt;
  if (ring.vars_.size() > kMaxPolyVariables) return std::nullopt;
  try {
    if (!ring.build_derivatives()) return std::nullopt;
    // Every expression converts (exponents in range), so callers may dereference from_ex.
    for (const auto& e : exprs)
      if (!ring.convert(e)) return std::nullopt;
  } catch (const PolyOverflow&) {
    return std::nullopt;
  }
  return ring;
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
  if (is_a<GiNaC::power>(e)) {
    const ex q = e.op(1);
    if (!is_a<GiNaC::numeric>(q) || !GiNaC::ex_to<GiNaC::numeric>(q).is_nonneg_integer() ||
        GiNaC::ex_to<GiNaC::numeric>(q) > 0xFF)
      return std::nullopt;
    const auto base = convert(e.op(0));
    if (!base) return std::nullopt;
    Poly acc = constant(1), sq = *base;
    for (long k = GiNaC::ex_to<GiNaC::numeric>(q).to_long(); k > 0; k >>= 1) {
      if (k & 1) acc = product(acc, sq);
      if (k > 1) sq = product(sq, sq);
    }
    return acc;
  }
  const auto v = find(e);
  if (!v) return std::nullopt;
  return variable(*v);
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
    for (std::size_t v = 0; v < vars_.size(); ++v)
      if (t->first.e[v] > 0) factors.push_back(GiNaC::pow(vars_[v].value, t->first.e[v]));
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
  GiNaC::numeric acc = 0;
  for (const auto& [m, c] : p.terms) {
    GiNaC::numeric t = GiNaC::numeric(cln::cl_N(c));
    for (std::size_t v = 0; v < values.size(); ++v)
      if (m.e[v] > 0) t *= m.e[v] == 1 ? values[v] : values[v].power(m.e[v]);
    acc += t;
  }
  return acc;
}

Poly PolyRing::derivative(const Poly& p, std::size_t state) const {
  Poly out;
  for (const auto& [m, c] : p.terms) {
    if (m.e[state] > 0) {
      Monomial r = m;
      --r.e[state];
      add_term(out, r, c * m.e[state]);
    }
    for (std::size_t v = states_; v < vars_.size(); ++v) {
      if (m.e[v] == 0 || derivs_[v][state].is_zero()) continue;
      Monomial r = m;
      --r.e[v];
      accumulate(out, r, c * m.e[v], derivs_[v][state]);
    }
  }
  return out;
}

Growth PolyRing::growth(const Poly& p) const {
  Growth g = Growth::constant;
  for (const auto& [m, c] : p.terms)
    for (std::size_t v = 0; v < vars_.size(); ++v)
      if (m.e[v] > 0 && var_growth_[v] > g) {
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
