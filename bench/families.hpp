// Scaled model families for the `obsynth check` benchmarks. Each family is a function of the
// state dimension n and produces the text of a `.sym` model (design.md §2):
//
//   chain  (a) linearizable by construction: the observer canonical form
//              z1' = l_1(u,y), z_i' = z_{i-1} + l_i(u,y), y = z_n (design.md §1) pulled back
//              through a polynomial triangular diffeomorphism with an explicit inverse,
//                T_n(x) = x1,  T_{n-k}(x) = x_{k+1} + psi_k(x_1..x_k),  k = 1..n-1,
//                psi_1 = x1^2/2, psi_k = x_1*x_k (k >= 2),
//                l_i = c_i*y^2 (c_i = (-1)^i/(i+1)) for i < n-1, l_{n-1} = sin(y),
//                l_n = -y^2/2 + u*(1+y^2),
//              so f = (dT/dx)^-1 (A T(x) + l(0,x1)), g = (dT/dx)^-1 (l(u,x1) - l(0,x1)),
//              obtained by forward substitution (dT/dx is unit lower triangular in the
//              ordering z_n, z_{n-1}, ..., z_1 against x1, ..., xn) and expanded.
//   cubic  (b) x_i' = x_{i+1} + x_i^2*x1 (i < n), x_n' = -(x1^3 + ... + xn^3), y = x1.
//   sine   (c) x_i' = x_{i+1} + sin(x_i) (i < n), x_n' = sin(x_n), y = x1.
//   nested (issue 6) the canonical form z1' = -sin(y) + (y^2+y-1) u, z_k' = z_{k-1} + y^2/k
//              (2 <= k <= n-1), z_n' = z_{n-1} - y^2/2 + (1+y) u, y = z_n, pulled back by
//              x_1 = z_n, x_k = -z_{n+1-k} + x_{k-1}^2/2: T is quadratic, T^-1 nested (degree
//              2^(n-1) once expanded). f and g are pushed forward recursively and written
//              in that nested (unexpanded) form:
//                f_1 = z_{n-1}(x) + l_n(0, x_1),
//                f_k = -(z_{n-k}(x) + l_{n+1-k}(0, x_1)) + x_{k-1} f_{k-1},
//              with z_{n-k}(x) = x_k^2/2 - x_{k+1} (k < n), z_0 = 0; g likewise with the
//              u-parts of l. Sizes 2..16.
//   dense  (issue 6) the nested model seen through the dense linear change of coordinates
//              x = M w, M_ij = min(i, j) (M = L U with L, U triangular matrices of ones:
//              det 1, integer inverse, tridiagonal), so that O is dense:
//              w' = M^-1 (f(M w) + g(M w, u)), y = (M w)_1. Sizes 2..16.
//
// Text is deterministic (obsynth::to_string orders operands itself), so regenerating a file
// gives the same bytes.
#pragma once

#include <ginac/ginac.h>

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace obsynth::bench {

enum class Family { chain, cubic, sine, nested, dense };

const char* family_name(Family f);
std::optional<Family> parse_family(std::string_view name);
std::vector<Family> all_families();
// The sizes the benchmarks run: 2, 4, 8, 12, 16.
std::vector<int> default_sizes();
// The sizes generated for a family: default_sizes(), or 2..16 for nested and dense.
std::vector<int> family_sizes(Family f);

// "<family>_n<N>", which is also the model name (a C++ identifier).
std::string model_name(Family f, int n);
// "<family>_n<N>.sym"
std::string model_file_name(Family f, int n);

// The `.sym` text of the family at size n (n >= 2).
std::string family_model(Family f, int n);

// The chain family's construction, exposed for tests and for the comments in the model file.
struct ChainConstruction {
  std::vector<GiNaC::symbol> x, z;
  GiNaC::symbol u, y;
  GiNaC::exvector T;          // T_1..T_n in x
  GiNaC::exvector T_inverse;  // x as a function of z
  GiNaC::exvector l;          // l_1..l_n in (u, y)
  GiNaC::exvector f, g;       // the model's fields, expanded
};
ChainConstruction chain_construction(int n);

// The nested (issue 6) family's construction. Its fields are nested, unexpanded expressions;
// T^-1 is the elimination sequence x_1 = z_n, x_k = -z_{n+1-k} + x_{k-1}^2/2 (k = 2..n),
// each step in z and the states of earlier steps.
struct NestedConstruction {
  std::vector<GiNaC::symbol> x, z;
  GiNaC::symbol u, y;
  GiNaC::exvector T;              // T_1..T_n in x
  GiNaC::exvector inverse_steps;  // x_k = inverse_steps[k-1], in z and x_1..x_{k-1}
  GiNaC::exvector l;              // l_1..l_n in (u, y)
  GiNaC::exvector f, g;           // pushed forward, nested
};
NestedConstruction nested_construction(int n);

// The dense family's coordinates: M (row-major, M_ij = min(i, j)) and its inverse.
std::vector<std::vector<int>> dense_matrix(int n);
std::vector<std::vector<int>> dense_matrix_inverse(int n);

}  // namespace obsynth::bench
