// Kou-Elliott-Tarn observer (seed 001 §4, Theorem 1, eq. 5-9):
//   xh' = f(xh) + g(xh, u) + L (h(xh) - y)            (seed eq. 5: L (yh - y))
// is an exponential observer when a constant L and a symmetric P > 0 make the symmetric part
//   S(x, u) = sym(P (dF/dx(x, u) + L dh/dx(x)))
// negative definite uniformly on the region (eq. 9). Over the declared domain box (convex, so
// the segment between x and xh stays in it while both do) the verdict is decided rigorously
// when certify/enclosure.hpp's interval eigenvalue bound (Gershgorin / midpoint + radius, with
// bisection) proves it, and is labelled sampled otherwise. L and P are searched on samples
// (pole placement on the linearisation, Lyapunov P, then Nelder-Mead on the largest sampled
// eigenvalue divided by sigma_max(P)) when the user gives none, then certified.
#pragma once

#include "designs/registry.hpp"

namespace obsynth {

Design kou_design();

}  // namespace obsynth
