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

namespace obsynth::c {
// The kernels the C++ runtime calls, by overload on the scalar type (float or double).
inline int discretise(const double* A, int n, double dt, double* E, double* G,
                      double* work) noexcept {
  return c_double::obsynth_discretise(A, n, dt, E, G, work);
}
inline int discretise(const float* A, int n, float dt, float* E, float* G, float* work) noexcept {
  return c_float::obsynth_discretise(A, n, dt, E, G, work);
}
inline int packed_positive_definite(const double* w, int off, int d, double* work) noexcept {
  return c_double::obsynth_packed_positive_definite(w, off, d, work);
}
inline int packed_positive_definite(const float* w, int off, int d, float* work) noexcept {
  return c_float::obsynth_packed_positive_definite(w, off, d, work);
}
inline int jet_update(double* eta, double* phi, double* cached_dt, double* y_prev, int K,
                      double epsilon, double dt, double y, double* work) noexcept {
  return c_double::obsynth_jet_update(eta, phi, cached_dt, y_prev, K, epsilon, dt, y, work);
}
inline int jet_update(float* eta, float* phi, float* cached_dt, float* y_prev, int K, float epsilon,
                      float dt, float y, float* work) noexcept {
  return c_float::obsynth_jet_update(eta, phi, cached_dt, y_prev, K, epsilon, dt, y, work);
}
inline int solve_cholesky(double* M, int d, const double* v, double* x) noexcept {
  return c_double::obsynth_solve_cholesky(M, d, v, x);
}
inline int solve_cholesky(float* M, int d, const float* v, float* x) noexcept {
  return c_float::obsynth_solve_cholesky(M, d, v, x);
}
inline int solve_lu(double* M, int d, const double* v, double* x) noexcept {
  return c_double::obsynth_solve_lu(M, d, v, x);
}
inline int solve_lu(float* M, int d, const float* v, float* x) noexcept {
  return c_float::obsynth_solve_lu(M, d, v, x);
}
}  // namespace obsynth::c
