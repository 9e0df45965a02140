// Rigorous enclosures of symbolic expressions over boxes (Arb ball arithmetic from FLINT,
// outward rounded, with branch and bound), and their sampled counterparts.
//
// A Bound labelled `rigorous` is a proven upper bound: every operation is done on Arb balls
// whose radii absorb all rounding errors, the box endpoints are rounded outward to doubles,
// and the reported double is rounded up. A Bound labelled `sampled` is a maximum over finitely
// many points (a lower estimate of the true supremum), and says so in `method`.
//
// Functions evaluated in balls: + * ^ (integer and rational exponents), sin, cos, tan, exp,
// log, tanh, atan, sqrt, abs, and the constant Pi. Anything else (or an expression that Arb
// cannot bound on the box, e.g. a pole inside it) falls back to sampling, said in `method`.
// Enclosures cover the points of the box where the expression is real: sqrt and rational
// powers are taken of the non-negative part of their argument's enclosure (natural-domain
// semantics); log of an enclosure reaching zero or below is "cannot bound".
#pragma once

#include <ginac/ginac.h>

#include <cstddef>
#include <string>
#include <vector>

#include "front/model.hpp"

namespace obsynth::certify {

struct Range {
  double lo, hi;
};

// A box over named symbols. Symbols of an expression that are not in `vars` are an error
// (std::invalid_argument naming the symbol).
struct Box {
  std::vector<GiNaC::symbol> vars;
  std::vector<Range> ranges;
};

// States, inputs and free parameters with Model::box(), endpoints rounded outward to double.
Box model_box(const Model& m);

enum class BoundKind { rigorous, sampled };
const char* bound_kind_name(BoundKind);  // "rigorous" / "sampled"

struct Bound {
  double value = 0;  // rigorous: proven upper bound; sampled: max over samples
  BoundKind kind = BoundKind::sampled;
  std::vector<double> worst_point;  // box point where the largest value was found (vars order)
  std::string method;               // e.g. "Arb balls, 1024 boxes" or "sampled, 4096 points"
};

// Branch and bound stops when the proven upper bound is within relative_gap of the largest
// value found at a point, or after max_boxes box evaluations (the bound stays rigorous, only
// looser).
// max_work (0: no limit) also caps the boxes at max_work / (ball operations per box, the
// compiled tape's length with its mean-value gradients): a deterministic cost cap for large
// expressions, where each box is expensive.
struct EnclosureBudget {
  std::size_t max_boxes = 4096;
  double relative_gap = 0.05;
  std::size_t max_work = 0;
};

// Deterministic sample points of the box: its centre, its corners (up to 2^12 of them) and a
// Halton sequence, n in all.
std::vector<std::vector<double>> sample_points(const Box& box, std::size_t n);

// sup over the box of |e|: rigorous when Arb can evaluate e, else falls back to sampled and
// says so.
Bound sup_abs(const GiNaC::ex& e, const Box& box, const EnclosureBudget& = {});
// Deterministic: box corners (up to 2^12 of them), centre, and a Halton sequence.
Bound sup_abs_sampled(const GiNaC::ex& e, const Box& box, std::size_t samples = 4096);
// sup over the box of the spectral norm ||M(x)||_2.
Bound matrix_norm_bound(const GiNaC::matrix& M, const Box& box, const EnclosureBudget& = {});
// sup over the (convex) box of ||D_x phi||_2 (a Lipschitz constant of phi in x on the box,
// uniform in the other box variables).
Bound lipschitz_bound(const std::vector<GiNaC::ex>& phi, const std::vector<GiNaC::symbol>& x,
                      const Box& box, const EnclosureBudget& = {});

// Is the symmetric S(x) negative definite on the whole box?
//   holds && kind == rigorous : proven (max_eigenvalue_bound < 0 is a proven upper bound of
//                               the largest eigenvalue of S over the box);
//   !holds && kind == rigorous: proven to fail: at worst_point a vector v with v' S v >= 0 was
//                               verified in ball arithmetic;
//   kind == sampled           : undecided by the enclosure within the budget (or Arb could not
//                               evaluate S); holds is the sampled verdict, method says so.
// max_eigenvalue_bound: an upper bound of the largest eigenvalue over the box (rigorous kind), or
// the sampled maximum (sampled kind). Bounds: the smaller of Gershgorin discs on the interval
// entries and lambda_max(midpoint) + ||radius||_2, with bisection.
struct DefinitenessVerdict {
  bool holds = false;
  BoundKind kind = BoundKind::sampled;
  double max_eigenvalue_bound = 0;
  std::vector<double> worst_point;
  std::string method;
};
DefinitenessVerdict negative_definite(const GiNaC::matrix& S, const Box& box,
                                      const EnclosureBudget& = {});

}  // namespace obsynth::certify
