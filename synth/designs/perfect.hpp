// Perfect observer (seed 003, Theorem 1 and Procedure 1): z as an explicit function of the
// jets y, y', ..., y^(n-1) and u, ..., u^(n-2); xh = T^-1(z). The jets come from the
// runtime's high-gain differentiators.
#pragma once

#include "designs/registry.hpp"

namespace obsynth {

Design perfect_design();

}  // namespace obsynth
