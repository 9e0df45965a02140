// The triangular normal form of seed 002 (Dufour, Flila & Hammouri, eq. 1-2), OUTPUT FIRST:
//   z' = A(u) z + phi(u, z),   y = C z = z_1,
// A(u) zero except its superdiagonal A(i, i+1) = a_i(u), and phi_i depending on (u, z_1..z_i)
// only. (The observer canonical form of seed 003 is the other convention: output last, ones on
// the subdiagonal; the two are never mixed.) With a_i(u) != 0 for every admissible u the system
// is uniformly observable (observable for every input, seed 002's definition); an a_i that
// vanishes at an admissible u makes that input blind to z_{i+1}.
//
// Two ways of finding it, tried in this order:
//  - states: z is a permutation of x (y = x_j, each x' affine in exactly one new state with a
//    coefficient free of x), exact and global;
//  - lie_derivatives: z = (h, L_f h, ..., L_f^{n-1} h) (drift f), so a_i = 1 and
//    phi_i = L_g L_f^{i-1} h for i < n, phi_n = L_{f+g} L_f^{n-1} h, each expressed in z
//    through an explicit inverse x = Z^-1(z) (an elimination sequence).
#pragma once

#include <ginac/ginac.h>

#include <optional>
#include <string>
#include <vector>

#include "front/model.hpp"
#include "symbolic/lie.hpp"
#include "symbolic/zero_test.hpp"

namespace obsynth {

// A value type other stages (high-gain, Kalman-theta designs) consume.
struct TriangularForm {
  enum class Coordinates { states, lie_derivatives };
  Coordinates coordinates = Coordinates::states;
  std::vector<GiNaC::symbol> z;    // z1 .. zn (fresh symbols, named "z1".."zn")
  std::vector<std::size_t> order;  // states: z_i = x_{order[i]}; empty for lie_derivatives
  ExVec z_of_x;                    // Z(x): z_i as expressions in x (and parameters)
  ExVec x_of_z;                    // Z^-1(z): x_j as expressions in z (and parameters)
  ExVec a;                         // a_1(u) .. a_{n-1}(u): free of x and z
  ExMatrix A;                      // n x n: A(i, i+1) = a_{i+1}(u) (0-based), zero elsewhere
  ExVec C;                         // the output row [1, 0, ..., 0]
  ExVec phi;                       // phi_i(u, z_1..z_i), i = 1..n
  ExVec phi_x;                     // phi_i(u, Z(x)) as expressions in x
};

const char* coordinates_name(TriangularForm::Coordinates c);  // "states", "lie_derivatives"

// The form for the model's whole field f + g (inputs as symbols), or nullopt with `why`
// saying which step failed. One output, u-free output map only (y = z_1). drift_lie, when
// given, is the drift chain L_f^k h, k = 0..n-1, already computed (Observability::lie[0]);
// lie_coordinates false skips the second way (it needs symbolic Lie derivatives).
std::optional<TriangularForm> triangular_form(const Model& m, std::string* why = nullptr,
                                              const ExVec* drift_lie = nullptr,
                                              bool lie_coordinates = true);

// Whether an expression in some variables (inputs, parameters, states) vanishes somewhere in
// their boxes:
//  never     - proved: every factor is a nonzero number, an exp(.), or a polynomial in one
//              variable with no real root in its closed box (Sturm sequence);
//  somewhere - proved: an exact root in the box (linear factor or a sampled point), or a sign
//              change between two sampled points (intermediate value theorem, continuous on
//              the box); `detail` names the witness;
//  unknown   - neither: no zero found at the sampled points, but not proved.
struct BoxZeros {
  enum Kind { never, somewhere, unknown } kind = unknown;
  std::string detail;
};
BoxZeros zeros_in_box(const GiNaC::ex& e, const SampleBoxes& boxes);

}  // namespace obsynth
