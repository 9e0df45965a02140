// Generic rank of the observability matrix without symbolic Lie derivatives (Sedoglavic's
// algorithm, as in StructuralIdentifiability.jl): along the trajectory from a random x0 with
// constant inputs, y^(k)(0) = k! * (k-th Taylor coefficient of y) = L_F^k h(x0), so the
// Jacobian of the Taylor coefficients with respect to x0 (forward mode) is O(x0) with its rows
// scaled by 1/k!. The expressions are walked as a DAG (shared subtrees once), so the cost is
// (DAG nodes) x (orders^2) x (states), whatever the size of the expanded Lie derivatives.
//
// Arithmetic: modulo a 62-bit prime for rational models (rank at a point is a lower bound of
// the generic rank; a rank deficit is wrong with probability at most the Schwartz-Zippel
// bound below), Arb balls otherwise (a pivot whose ball excludes 0 is a proven nonzero, so
// the rank found is a proven lower bound; that it is not larger rests on the points tried).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "foundation/budget.hpp"
#include "front/model.hpp"

namespace obsynth {

struct JetsOptions {
  int points = 2;                  // independent random points (modular: each its own prime)
  long precision_bits = 128;       // ball arithmetic: first working precision
  long max_precision_bits = 4096;  // doubled until two precisions agree on the rank
  std::uint64_t seed = 0x0b5e7;
  bool force_ball = false;  // balls even for a rational model (tests compare the two)
};

enum class JetsArithmetic { modular, ball };

struct JetsRank {
  JetsArithmetic arithmetic = JetsArithmetic::modular;
  std::size_t n = 0, p = 0;
  std::size_t rank = 0;               // of O = d(L_f^k h): drift only, inputs 0
  std::size_t rank_inputs = 0;        // of O_u: constant random inputs (= rank without inputs)
  std::vector<std::size_t> indices;   // observability indices (drift), sum = rank
  std::vector<std::size_t> selected;  // rows (k-major, as Observability::rows) kept
  int points = 0;                     // points that evaluated (each decides both ranks)
  std::vector<std::uint64_t> primes;  // modular: the prime of each point
  long precision_bits = 0;            // ball: the precision that settled the rank
  std::size_t dag_nodes = 0;
  // modular: total degree bound D of the numerator of a maximal minor of O (O_u), in the
  // states, free parameters (and inputs); the probability that a rank below n is an
  // under-estimate is at most prod_i 2 D / p_i over the points (Schwartz-Zippel; the factor 2
  // covers conditioning on the point being regular).
  unsigned long degree_bound = 0, degree_bound_inputs = 0;
  double error_bound = 0, error_bound_inputs = 0;  // 0: full rank, proven
  std::string method;                              // one line for reports
};

// Throws UserError when the model uses something the Taylor arithmetic cannot handle, or
// when no sampled point is regular.
JetsRank jets_rank(const Model& m, const JetsOptions& opt = {}, const Budget* budget = nullptr);

}  // namespace obsynth
