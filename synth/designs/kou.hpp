// Kou-Elliott-Tarn observer (seed 001 §4, Theorem 1, eq. 5-9):
//   xh' = f(xh) + g(xh, u) + L (h(xh) - y)            (seed eq. 5: L (yh - y))
// is an exponential observer when a constant L and a symmetric P > 0 make the symmetric part
//   S(x, u) = sym(P (dF/dx(x, u) + L dh/dx(x)))
// negative definite uniformly on the region (eq. 9). Over the declared domain box (convex, so
// the segment between x and xh stays in it while both do) the verdict is decided rigorously
// when certify/enclosure.hpp's interval eigenvalue bound (Gershgorin / midpoint + radius, with
// bisection) proves it, and is labelled sampled otherwise. L and P are searched on samples
// (pole placement on the linearisation, Lyapunov P, then Nelder-Mead on the largest sampled
// eigenvalue divided by sigma_max(P)) when the user gives none, then certified. Past 4 states
// Nelder-Mead scores on an active subset of the samples under an evaluation budget, and the
// enclosure runs under a work cap (kou.cpp, kExhaustiveStates).
#pragma once

#include "designs/registry.hpp"

namespace obsynth {

Design kou_design();

// The numbers behind the Kou verdict (for reports and tests).
struct KouCertificate {
  std::string not_applicable;
  std::vector<double> L, P;         // row-major, n x p and n x n (the exact values, rounded)
  bool holds = false;               // negative definite (proven when rigorous, else on samples)
  bool rigorous = false;            // the enclosure decided (holds: proven; !holds: proven to fail)
  double max_eigenvalue_bound = 0;  // rigorous: upper bound over the domain; else sampled max
  double sampled_max_eigenvalue = 0;
  std::vector<double> worst_point;  // model_box order: states, inputs, free parameters
  double sigma_min_P = 0, sigma_max_P = 0;
};
KouCertificate kou_certificate(const Model& m, const DesignOptions& o = {});

}  // namespace obsynth
