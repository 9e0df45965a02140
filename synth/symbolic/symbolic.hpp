// Small symbolic utilities shared by the stages.
#pragma once

#include <ginac/ginac.h>

#include <cstddef>
#include <optional>
#include <vector>

namespace obsynth {

// Symbols occurring in e, sorted by name (deterministic).
std::vector<GiNaC::symbol> symbols_in(const GiNaC::ex& e);
bool depends_on(const GiNaC::ex& e, const std::vector<GiNaC::symbol>& syms);
// Number of nodes in the expression tree (shared subtrees counted each time).
std::size_t expression_size(const GiNaC::ex& e);
// True if e contains a function call or a non-integer power.
bool has_transcendental(const GiNaC::ex& e);
// True if e divides by something that depends on syms (a negative power with such a base):
// a tree walk, no normalisation.
bool has_denominator_in(const GiNaC::ex& e, const std::vector<GiNaC::symbol>& syms);
// Row vector d(e)/d(vars).
std::vector<GiNaC::ex> gradient(const GiNaC::ex& e, const std::vector<GiNaC::symbol>& vars);
// True when e has a negative power of a non-numeric base (or tan) anywhere.
bool has_symbolic_denominator(const GiNaC::ex& e);
// The terms of an expanded function argument: rational coefficient times a monomial (1 for
// a number); nullopt when a coefficient is not rational (a float).
struct ArgumentTerm {
  GiNaC::numeric coeff;
  GiNaC::ex monomial;
};
std::optional<std::vector<ArgumentTerm>> argument_terms(const GiNaC::ex& arg);
// arg = multiple * key, key with rational content 1 and its first term (by printed text, so
// that the choice does not depend on GiNaC's run-dependent term order) positive.
struct ArgumentDirection {
  GiNaC::numeric multiple;
  GiNaC::ex key;
};
std::optional<ArgumentDirection> argument_direction(const GiNaC::ex& arg);
// gcd(p1/q1, p2/q2) = gcd(p1, p2) / lcm(q1, q2), positive.
GiNaC::numeric rational_gcd(const GiNaC::numeric& a, const GiNaC::numeric& b);

// Simplify for storage, with canonical atoms: polynomials (in symbols and exp, sin/cos, tanh
// atoms) go through the polynomial ring (exp(a)*exp(b) -> exp(a+b), exp Laurent, sin/cos of
// integer multiples of one angle as powers of that angle's sin/cos); other polynomials are
// expanded (with exp factors combined and multiple angles reduced); rational expressions are
// normal()ized with exp factors cancelled across numerator and denominator.
GiNaC::ex simplify(const GiNaC::ex& e);
// Every product's exp factors (and integer powers of them) as one exp of the expanded sum
// of their arguments, dropped when that sum is 0.
GiNaC::ex combine_exponentials(const GiNaC::ex& e);

}  // namespace obsynth
