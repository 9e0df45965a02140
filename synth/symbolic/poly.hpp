// Sparse polynomials over Q for the differentiation-heavy stages (Lie chains, gradients,
// brackets of polynomial fields). GiNaC's generic add/mul trees spend most of their time on
// allocation and canonical reordering; a Lie derivative of a polynomial model is a sum of
// products of terms, which a hash map of packed exponent vectors does an order of magnitude
// faster. The "variables" are the states, other symbols (parameters) and function atoms
// whose derivatives stay in the ring, kept canonical so that identities between atoms are
// identities of polynomials:
//  - exp: one base exp(g*t) per monomial t of the arguments (g the rational gcd of t's
//    coefficients); exp(c1*t1 + c2*t2) is the Laurent monomial base1^(c1/g1) base2^(c2/g2),
//    so exp(a)*exp(-a) is 1 (exponents are signed; only exp bases take negative ones);
//  - sin/cos: one pair of bases sin(g*B), cos(g*B) per direction B (the argument divided by
//    its rational content, sign fixed); sin(k*g*B), cos(k*g*B) expand by de Moivre;
//  - tanh of an argument with a fixed sign.
// Anything else (denominators, sqrt, log, atan, tan) is outside the ring and the caller
// keeps GiNaC's path.
#pragma once

#include <ginac/ginac.h>

#include <cln/rational.h>
#include <array>
#include <cstdint>
#include <optional>
#include <unordered_map>
#include <vector>

namespace obsynth {

inline constexpr std::size_t kMaxPolyVariables = 64;

struct Monomial {
  std::array<std::int8_t, kMaxPolyVariables> e{};  // exponents (negative for exp bases only)
  bool operator==(const Monomial& o) const { return e == o.e; }
};

struct MonomialHash {
  std::size_t operator()(const Monomial& m) const noexcept;
};

struct Poly {
  std::unordered_map<Monomial, cln::cl_RA, MonomialHash> terms;
  bool is_zero() const { return terms.empty(); }
  // Nodes of the GiNaC tree to_ex would build (for budgets, before building it).
  std::size_t node_estimate() const;
};

// How a function grows in x: constant, bounded (with bounded derivatives' arguments aside),
// or possibly unbounded.
enum class Growth { constant, bounded, unbounded };

// Thrown when an exponent would leave the packed range; callers fall back to GiNaC.
struct PolyOverflow {};

class PolyRing {
 public:
  // A ring holding every expression of `exprs` with the states x as the first variables, or
  // nullopt when some expression is not a polynomial in states, symbols and closed atoms.
  static std::optional<PolyRing> for_expressions(const std::vector<GiNaC::ex>& exprs,
                                                 const std::vector<GiNaC::symbol>& x);
  // e with canonical atoms (to_ex of its polynomial in a ring of its own), converted once;
  // nullopt when e is outside the ring.
  static std::optional<GiNaC::ex> canonical_form(const GiNaC::ex& e);

  // e (any expression in the ring's variables) as a polynomial; nullopt outside the ring.
  std::optional<Poly> from_ex(const GiNaC::ex& e) const;
  // The expanded GiNaC expression of p.
  GiNaC::ex to_ex(const Poly& p) const;

  Poly derivative(const Poly& p, std::size_t state) const;  // d/dx_state
  static Poly product(const Poly& a, const Poly& b);
  static void add_to(Poly& acc, const Poly& p, const cln::cl_RA& scale = 1);
  static void subtract_from(Poly& acc, const Poly& p) { add_to(acc, p, minus_one()); }
  // -1 built by negation: CLN's inline cl_RA(int) left-shifts negative values (undefined
  // behaviour that UBSan reports in our translation units).
  static cln::cl_RA minus_one() { return -cln::cl_RA(1); }
  // The Lie derivative sum_j grad[j] * field[j].
  static Poly dot(const std::vector<Poly>& grad, const std::vector<Poly>& field);

  // Values of the ring's variables at a point (exact symbol values rounded to `digits`, atoms
  // evaluated there); nullopt when some variable has no real value at the point.
  std::optional<std::vector<GiNaC::numeric>> values_at(const GiNaC::exmap& point, int digits) const;
  // p at those values (callers hold the GiNaC::Digits setting used for them).
  static GiNaC::numeric evaluate(const Poly& p, const std::vector<GiNaC::numeric>& values);

  // constant: free of x; bounded: a polynomial in sin/cos/tanh of x and x-free symbols;
  // unbounded otherwise (a state or exp of x occurs).
  Growth growth(const Poly& p) const;

  std::size_t states() const { return states_; }

 private:
  enum class Kind { state, symbol, sin, cos, exp, tanh };
  struct Variable {
    GiNaC::ex value;  // the symbol or the atom
    Kind kind;
    GiNaC::ex arg;  // atom argument
  };
  // A family of atoms sharing one base: exp(c*key) (key a monomial) or sin/cos(c*key) (key a
  // direction), with c an integer multiple of `unit`. Bases are created once all units are
  // known, in the order their families were first met (inner atoms first).
  struct Family {
    Kind kind;  // exp or sin (sin stands for the sin/cos pair)
    GiNaC::ex key;
    GiNaC::numeric unit;
    std::size_t var = 0;  // the base (for sin: the sin base; cos is var + 1)
  };
  std::size_t states_ = 0;
  std::vector<Variable> vars_;
  std::vector<Family> families_;
  // Families (index) and tanh atoms (argument) in order of discovery, inner atoms first.
  struct Pending {
    std::optional<std::size_t> family;
    GiNaC::ex tanh_arg;
  };
  std::vector<Pending> pending_;
  // d var / d x_j for atoms: derivs_[v][j], empty poly when independent of x_j.
  std::vector<std::vector<Poly>> derivs_;
  std::vector<Growth> var_growth_;

  std::optional<std::size_t> find(const GiNaC::ex& v) const;
  std::optional<std::size_t> find_family(Kind kind, const GiNaC::ex& key) const;
  void note_family(Kind kind, const GiNaC::ex& key, const GiNaC::numeric& multiple);
  bool register_atoms(const GiNaC::ex& e);
  bool register_function(const GiNaC::ex& e);
  bool create_bases();
  bool build_derivatives();
  std::optional<Poly> convert(const GiNaC::ex& e) const;
  std::optional<Poly> convert_function(const GiNaC::ex& e) const;
  std::optional<Poly> convert_power(const GiNaC::ex& e) const;

 public:
  // Number of ring variables (states first, then symbols and atoms): exponent slots in use.
  std::size_t variables() const { return vars_.size(); }
};

}  // namespace obsynth
