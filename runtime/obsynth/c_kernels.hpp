// SPDX-License-Identifier: MIT
// Copyright (c) obsynth authors
//
// The C99 kernels of runtime/obsynth/c/kernels.h for C++, once per precision:
// obsynth::c_double::obsynth_discretise, obsynth::c_float::obsynth_solve_lu, ... The C back
// end's generated sources include the same text, the C++ runtime wraps it (discretise.hpp), and
// obsynth's simulator calls it: one implementation of each kernel.
#pragma once

#include <cmath>
#include <type_traits>

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
inline void rk4_stage(int stage, double h, int n, const double* w0, const double* k, double* acc,
                      double* t) noexcept {
  c_double::obsynth_rk4_stage(stage, h, n, w0, k, acc, t);
}
inline void rk4_stage(int stage, float h, int n, const float* w0, const float* k, float* acc,
                      float* t) noexcept {
  c_float::obsynth_rk4_stage(stage, h, n, w0, k, acc, t);
}
// Newton by reverse communication (obsynth_newton_*): the state per precision and its verdicts.
template <class Scalar>
using newton_state = std::conditional_t<std::is_same_v<Scalar, float>, c_float::obsynth_newton,
                                        c_double::obsynth_newton>;
constexpr int newton_running = c_double::OBSYNTH_NEWTON_RUNNING;
constexpr int newton_converged = c_double::OBSYNTH_NEWTON_CONVERGED;
constexpr int newton_not_converged = c_double::OBSYNTH_NEWTON_NOT_CONVERGED;
inline void newton_begin(c_double::obsynth_newton* s, const double* z, const double* x, int n,
                         int iterations, double tol) noexcept {
  c_double::obsynth_newton_begin(s, z, x, n, iterations, tol);
}
inline void newton_begin(c_float::obsynth_newton* s, const float* z, const float* x, int n,
                         int iterations, float tol) noexcept {
  c_float::obsynth_newton_begin(s, z, x, n, iterations, tol);
}
inline int newton_residual(c_double::obsynth_newton* s, const double* Tx, const double* z, int n,
                           double* r, double* x, const double* x_prev) noexcept {
  return c_double::obsynth_newton_residual(s, Tx, z, n, r, x, x_prev);
}
inline int newton_residual(c_float::obsynth_newton* s, const float* Tx, const float* z, int n,
                           float* r, float* x, const float* x_prev) noexcept {
  return c_float::obsynth_newton_residual(s, Tx, z, n, r, x, x_prev);
}
inline void newton_step(const double* tau, const double* r, int n, double* dx) noexcept {
  c_double::obsynth_newton_step(tau, r, n, dx);
}
inline void newton_step(const float* tau, const float* r, int n, float* dx) noexcept {
  c_float::obsynth_newton_step(tau, r, n, dx);
}
inline void newton_apply(c_double::obsynth_newton* s, const double* dx, int n, double* x,
                         double* x_prev) noexcept {
  c_double::obsynth_newton_apply(s, dx, n, x, x_prev);
}
inline void newton_apply(c_float::obsynth_newton* s, const float* dx, int n, float* x,
                         float* x_prev) noexcept {
  c_float::obsynth_newton_apply(s, dx, n, x, x_prev);
}
inline void exact_step(const double* E, const double* G, const double* w0, const double* c, int n,
                       int k, int increment, double* w1) noexcept {
  c_double::obsynth_exact_step(E, G, w0, c, n, k, increment, w1);
}
inline void exact_step(const float* E, const float* G, const float* w0, const float* c, int n,
                       int k, int increment, float* w1) noexcept {
  c_float::obsynth_exact_step(E, G, w0, c, n, k, increment, w1);
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
