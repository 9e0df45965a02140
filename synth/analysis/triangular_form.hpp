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
//
// With p > 1 outputs (block_triangular_form) the form has one block per output, of size k_i
// (the observability indices), output first in each block: z = (z_{1,1}..z_{1,k_1}, ...,
// z_{p,1}..z_{p,k_p}), y_i = z_{i,1} (C selects each block's first coordinate), A(u) =
// blockdiag(A_i(u)) with a_{i,j}(u) on each block's superdiagonal (zero between blocks), and phi
// triangular by level: phi_{i,j} depends on (u, z_{l,1..j}) of every block l only (the level of
// z_{l,m} is m; p = 1 is the form above).
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
  // Block sizes k_1..k_p (empty: one block, p = 1). `a` is then the whole superdiagonal, zero
  // between blocks, and C (above) the first output's row only: see block_starts.
  std::vector<std::size_t> blocks;
};

// Rows of z by block: row r's block (0-based) and level (1-based, its place in the block); the
// first row of every block (where C has its ones); the label "r+1" (one block) or "i,j".
std::size_t block_of(const std::vector<std::size_t>& blocks, std::size_t r);
std::size_t level_of(const std::vector<std::size_t>& blocks, std::size_t r);
std::vector<std::size_t> block_starts(const std::vector<std::size_t>& blocks);
std::string z_label(const std::vector<std::size_t>& blocks, std::size_t r);

const char* coordinates_name(TriangularForm::Coordinates c);  // "states", "lie_derivatives"

// The form for the model's whole field f + g (inputs as symbols), or nullopt with `why`
// saying which step failed. One output, u-free output map only (y = z_1). drift_lie, when
// given, is the drift chain L_f^k h, k = 0..n-1, already computed (Observability::lie[0]);
// lie_coordinates false skips the second way (it needs symbolic Lie derivatives).
std::optional<TriangularForm> triangular_form(const Model& m, std::string* why = nullptr,
                                              const ExVec* drift_lie = nullptr,
                                              bool lie_coordinates = true);

// p >= 1 outputs with observability indices k (sum n): the block form in the coordinates
// z_{i,j} = L_f^{j-1} h_i (a = 1 inside the blocks, phi_{i,j} = L_g z_{i,j} for j < k_i,
// phi_{i,k_i} = L_{f+g} z_{i,k_i}), through an explicit inverse; nullopt with `why` naming the
// first entry that breaks the level condition (or the step that failed).
std::optional<TriangularForm> block_triangular_form(const Model& m,
                                                    const std::vector<std::size_t>& indices,
                                                    std::string* why = nullptr);

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
