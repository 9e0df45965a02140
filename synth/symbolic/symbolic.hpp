// Small symbolic utilities shared by the stages.
#pragma once

#include <ginac/ginac.h>

#include <cstddef>
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
// Simplify for storage: expand() for polynomials (in symbols and function atoms), normal()
// for rational expressions; keeps transcendental atoms.
GiNaC::ex simplify(const GiNaC::ex& e);

}  // namespace obsynth
