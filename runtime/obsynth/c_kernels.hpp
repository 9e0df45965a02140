// SPDX-License-Identifier: MIT
// Copyright (c) obsynth authors
//
// The C99 kernels of runtime/obsynth/c/kernels.h for C++, once per precision:
// obsynth::c_double::obsynth_discretise, obsynth::c_float::obsynth_solve_lu, ... The C back
// end's generated sources include the same text, the C++ runtime wraps it (discretise.hpp), and
// obsynth's simulator calls it: one implementation of each kernel.
#pragma once

#include <cmath>

namespace obsynth::c_double {
using Scalar = double;
#include "obsynth/c/kernels.h"
}  // namespace obsynth::c_double

namespace obsynth::c_float {
using Scalar = float;
#define OBSYNTH_C_FLOAT 1
#include "obsynth/c/kernels.h"
#undef OBSYNTH_C_FLOAT
}  // namespace obsynth::c_float
