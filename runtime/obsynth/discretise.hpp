// SPDX-License-Identifier: MIT
// Copyright (c) obsynth authors
//
// Exact discretisation of a linear system w' = A w + c with c held over a step (zero-order
// hold): w(t + dt) = Phi w(t) + Gamma c with
//   Phi = e^{A dt},   Gamma = int_0^dt e^{A s} ds.
// It returns E = Phi - I rather than Phi, and the step is taken as an increment,
//   w <- w + (E w + Gamma c),
// because for small ||A dt|| the entries of Phi round to 1 + O(eps) in float: the rounding of
// Phi would act like a perturbation of A of relative size eps / ||A dt|| (1e-4 in float at
// dt = 1e-4), which a steady input turns into a steady estimation error. E keeps the full
// relative precision of the small terms (as expm1 does for scalars).
// Computed by scaling and squaring: the Taylor series of both on h = dt / 2^s with
// ||A h|| <= 1/2 (terms summed until they no longer change the sum), then s doublings
//   E(2h) = E(h) (E(h) + 2 I),   Gamma(2h) = Gamma(h) + (E(h) + I) Gamma(h).
// This is exact up to rounding (no truncation of the time discretisation, unlike RK4), has no
// heap, and runs only when dt changes.
#pragma once

#include <cmath>
#include <type_traits>

#include "obsynth/c_kernels.hpp"
#include "obsynth/eigen.hpp"
#include "obsynth/numeric.hpp"

namespace obsynth {

/// E = e^{A dt} - I and Gamma (see above) by the C kernel obsynth_discretise. Eigen's matrices
/// are column-major: read as row-major they are the transposes, and the kernel's series and
/// doublings commute with transposition, so A's storage goes in and E's and Gamma's come out
/// as they are. False for a bad dt or a non-finite result.
template <class Scalar, int N>
bool discretise_linear(const Eigen::Matrix<Scalar, N, N>& A, Scalar dt,
                       Eigen::Matrix<Scalar, N, N>& E,
                       Eigen::Matrix<Scalar, N, N>& Gamma) noexcept {
  static_assert(std::is_same<Scalar, float>::value || std::is_same<Scalar, double>::value,
                "discretise_linear: float or double");
  Scalar work[4 * N * N];
  return c::discretise(A.data(), N, dt, E.data(), Gamma.data(), work) != 0;
}

}  // namespace obsynth

namespace obsynth {

/// One exact zero-order-hold step of w' = A w + c, prepared once per dt. In single precision
/// it keeps E = Phi - I and steps by increments, w <- w + (E w + Gamma c) (see above: Phi's
/// entries would round to 1 + O(eps)); in double the rounding of Phi is negligible
/// (eps / ||A dt|| ~ 1e-13 at dt = 1e-3) and the direct w <- Phi w + Gamma c saves n additions.
/// With K != N (or a matrix B given to prepare), the held input is c = B b for a constant
/// N x K matrix B and a K-vector b: the step then applies Gamma B, folded once per dt, to b,
/// which costs N K instead of N^2 multiply-adds plus the N entries of c.
template <class Scalar, int N, int K = N>
class ExactLinearStep {
 public:
  using Mat = Eigen::Matrix<Scalar, N, N>;
  using InputMap = Eigen::Matrix<Scalar, N, K>;
  using Vec = Eigen::Matrix<Scalar, N, 1>;
  using In = Eigen::Matrix<Scalar, K, 1>;
  static constexpr bool kIncrement = sizeof(Scalar) < sizeof(double);

  /// Whether E and Gamma are ready for this dt.
  bool ready(Scalar dt) const noexcept { return dt == dt_; }
  /// Computes them for dt; false (and not ready) on a bad dt or a non-finite result. Kept out
  /// of line: it runs once per sample period, and inlined it would crowd the step's hot path.
#if defined(__GNUC__)
  __attribute__((noinline, cold))
#endif
  bool
  prepare(const Mat& A, Scalar dt) noexcept {
    static_assert(K == N, "prepare(A, dt) is for c itself as the input; give B otherwise");
    dt_ = Scalar(0);
    if (!discretise_linear<Scalar, N>(A, dt, M_, Gamma_)) return false;
    if (!kIncrement) M_ += Mat::Identity();
    dt_ = dt;
    return true;
  }
  /// The same for c = B b: keeps Gamma B.
#if defined(__GNUC__)
  __attribute__((noinline, cold))
#endif
  bool
  prepare(const Mat& A, const InputMap& B, Scalar dt) noexcept {
    dt_ = Scalar(0);
    Mat Gamma;
    if (!discretise_linear<Scalar, N>(A, dt, M_, Gamma)) return false;
    if (!kIncrement) M_ += Mat::Identity();
    Gamma_.noalias() = Gamma * B;
    if (!all_finite(Gamma_)) return false;
    dt_ = dt;
    return true;
  }
  /// w(t + dt) from w(t) and the held input: w + (E w + G c) in single precision (w added last,
  /// once: the increment keeps its full relative precision), M w + G c otherwise (G = Gamma or
  /// Gamma B). The arithmetic of the C kernel obsynth_exact_step, operation for operation (G c
  /// first, then M's columns by multiply-adds, so w enters the step-to-step dependency chain
  /// through one multiply-add per column: seed 003's step at 0.9 of the expert's time rather
  /// than 1.0; test_c_kernels checks the two agree bit for bit). Written in Eigen packets rather
  /// than calling the kernel: through the kernel GCC 12 stores the new state as scalars and
  /// reloads it as a packet, and the store-forwarding stalls double the step's time.
  /// Coefficient-based products (lazyProduct): unrolled with compile-time sizes, never a call
  /// into Eigen's general GEMV kernel (which a plain fixed-size product becomes from N = 8 on).
  Vec apply(const Vec& w, const In& c) const noexcept {
    Vec r = Gamma_.lazyProduct(c);
    for (int j = 0; j < N; ++j) r += M_.col(j) * w(j);
    if constexpr (kIncrement) {
      return w + r;
    } else {
      return r;
    }
  }

 private:
  Mat M_ = Mat::Zero();                ///< Phi - I (single precision) or Phi
  InputMap Gamma_ = InputMap::Zero();  ///< Gamma, or Gamma B
  Scalar dt_ = Scalar(0);              ///< 0: not prepared
};

}  // namespace obsynth
