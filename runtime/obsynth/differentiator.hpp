// SPDX-License-Identifier: MIT
// Copyright (c) obsynth authors
//
// JetDifferentiator<Scalar, K>: on-line estimate of the output jet (y, y', ..., y^(K)) from
// samples of y, as needed by the "perfect observer" (which rebuilds the state algebraically
// from y and its derivatives). Fixed size, allocation-free, noexcept.
//
// ---------------------------------------------------------------------------------------
// Method: linear high-gain differentiator, discretised exactly
// ---------------------------------------------------------------------------------------
// Continuous time, with tuning parameter epsilon > 0 (a time constant, in the units of t):
//
//   xi_i' = xi_{i+1} + l_i (y - xi_0),  i = 0..K-1
//   xi_K' =            l_K (y - xi_0),      l_i = C(K+1, i+1) / epsilon^(i+1)
//
// so the characteristic polynomial of the error dynamics is (s + 1/epsilon)^(K+1): all poles
// at -1/epsilon, no overshoot-prone complex pairs. xi_k is the estimate of y^(k).
//
// With eta_i = epsilon^i xi_i and h = dt/epsilon this becomes eta' = (M eta + alpha y)/epsilon
// with integer matrices: M = S - alpha e_0^T (S = upper shift, alpha_i = C(K+1, i+1)), and
// N = M + I is nilpotent (N^(K+1) = 0 by Cayley-Hamilton). Hence the transition matrix over
// one sample interval is a finite sum, computed exactly (no series truncation):
//
//   Phi(h) = exp(M h) = e^{-h} sum_{j=0..K} (h N)^j / j!
//
// Between samples y is taken as the straight line through the previous and the current sample
// (first-order hold). For y = a + b t the jet (a + b t, b, 0, ..., 0) solves the equations
// exactly, so with slope b = (y_n - y_{n-1})/dt the update
//
//   eta_n = p_n + Phi(h) (eta_{n-1} - p_{n-1}),  p = (y, epsilon b, 0, ..., 0)
//
// is the exact solution of the continuous filter driven by the piecewise-linear interpolant of
// the samples. Consequences: stable for every dt > 0 and every epsilon > 0 (spectral radius of
// Phi is e^{-h} < 1), no stiffness limit, and the only discretisation error is the
// interpolation error of y between samples. Phi is cached and recomputed only when dt (or
// epsilon) changes; an update then costs (K+1)^2 multiply-adds. K = 0 is the identity
// (derivative(0) = last sample), since no derivative is requested.
//
// ---------------------------------------------------------------------------------------
// Accuracy versus noise (derivative k, 0 <= k <= K; M_j = sup |y^(j)|)
// ---------------------------------------------------------------------------------------
// The estimation error e = xi - (y, y', ..., y^(K)) obeys, in Laplace form,
//   e_k = -P_k(s) / (s + 1/epsilon)^(K+1) * y^(K+1)  +  H_k(s) v
// with P_k(s) = sum_{j<=k} C(K+1, j) epsilon^-j s^(k-j), v the measurement error and H_k the
// filter from y to xi_k. This gives, after the start-up transient has died out:
//
// 1. Truncation (bias) error -- the filter is exact for polynomials of degree <= K:
//      |e_k| <= C(K+1, k) * epsilon^(K+1-k) * M_{K+1}.
//    The impulse response of P_k(s)/(s+1/epsilon)^(K+1) is non-negative, so this bound is
//    attained for constant y^(K+1): e_k = -C(K+1, k) epsilon^(K+1-k) y^(K+1) exactly.
//    For y = A sin(w t) the steady error amplitude is |P_k(jw)/(jw + 1/epsilon)^(K+1)| A w^(K+1)
//    (<= the bound above, and ~ the bound when w epsilon << 1).
//
// 2. Noise amplification -- derivative k amplifies noise by epsilon^-k:
//    bounded noise |v| <= delta:         |e_k| <= G_k * delta / epsilon^k
//    white sampled noise, std sigma:      std(e_k) ~= N_k * sigma * sqrt(dt/epsilon) / epsilon^k
//    (the second for dt << epsilon; sigma^2 dt is the low-frequency noise density after the
//    first-order hold). G_k = L1 norm and N_k = L2 norm of the impulse response of
//    H_k at epsilon = 1:
//
//        K  k | C(K+1,k)   G_k     N_k          K  k | C(K+1,k)   G_k     N_k
//        1  0 |    1     1.2707  1.1180         3  0 |    1     1.6096  1.7048
//        1  1 |    2     0.7358  0.5000         3  1 |    4     2.9909  2.4044
//        2  0 |    1     1.4601  1.4361         3  2 |    6     2.1678  1.5910
//        2  1 |    3     1.7507  1.3229         3  3 |    4     0.5597  0.3953
//        2  2 |    3     0.6200  0.4330
//    (N_k^2 is rational: K=1: 5/4, 1/4; K=2: 33/16, 7/4, 3/16; K=3: 93/32, 185/32, 81/32, 5/32.)
//
// 3. Trade-off: error_k(epsilon) <= C(K+1,k) epsilon^(K+1-k) M_{K+1} + G_k delta epsilon^-k is
//    minimised at epsilon* ~ (delta / M_{K+1})^(1/(K+1)), where
//    error_k ~ M_{K+1}^(k/(K+1)) delta^((K+1-k)/(K+1)). Halving epsilon divides the bias of
//    derivative k by 2^(K+1-k) and multiplies its (white) noise by 2^(k+1/2).
//
// 4. Sampling: the first-order hold misses |y_FOH - y| <= dt^2 M_2 / 8. Treated as noise this
//    is bounded by G_k dt^2 M_2 / (8 epsilon^k); but its mean over a step is dt^2 y''/12 and
//    the rest oscillates at the sampling rate, which the filter rejects, so the actual effect
//    is e_k ~= dt^2 y^(k+2) / 12, negligible for dt << epsilon.
//    Keep dt <= epsilon / 10 so that the filter resolves the signal; larger dt stays stable
//    but the estimate then lags by the interpolation error.
//
// ---------------------------------------------------------------------------------------
// Start-up transient
// ---------------------------------------------------------------------------------------
// reset(y0) sets xi = (y0, 0, ..., 0), so the initial error is (0, -y'(0), ..., -y^(K)(0)).
// It decays as e^{-t/epsilon} times a polynomial of degree K in t/epsilon:
//   e_k(t) = -epsilon^-k sum_{i>=1} [Phi(t/epsilon)]_{k,i} epsilon^i y^(i)(0)
// so derivative k >= 2 peaks at ~ epsilon^(1-k) |y'(0)| shortly after reset. The row-sum norm
// of Phi(tau) falls below 1e-3 (1e-6) for tau >= 9.9 (17.4) at K = 1, 13.1 (21.0) at K = 2,
// 15.7 (23.9) at K = 3, 18.5 (27.0) at K = 4: discard about 15-25 epsilon of output after a
// reset, or seed the full jet with reset(jet0) when the derivatives are known.
//
// ---------------------------------------------------------------------------------------
// Usage
// ---------------------------------------------------------------------------------------
//   obsynth::JetDifferentiator<float, 2> d(0.02f);  // epsilon = 20 ms
//   d.reset(y0);
//   every sample:  d.update(dt, y);  float dy = d.derivative(1);
// For float, keep epsilon^K well inside the float range and K small (<= 4): the estimate of
// derivative k carries rounding noise ~ 1e-7 |y| epsilon^-k.
#pragma once

#include <cmath>
#include <limits>
#include <type_traits>

#include "obsynth/c_kernels.hpp"
#include "obsynth/eigen.hpp"
#include "obsynth/numeric.hpp"
#include "obsynth/status.hpp"

namespace obsynth {

template <class Scalar, int K>
class JetDifferentiator {
  static_assert(K >= 0, "JetDifferentiator: K is the highest derivative order, K >= 0");

 public:
  static constexpr int order = K;
  using Jet = Eigen::Matrix<Scalar, K + 1, 1>;
  using TransitionMatrix = Eigen::Matrix<Scalar, K + 1, K + 1>;

  /// Default tuning epsilon = 0.01 (time units of dt).
  JetDifferentiator() noexcept : JetDifferentiator(default_epsilon()) {}

  /// epsilon > 0: time constant of the (K+1)-fold pole at -1/epsilon. An invalid value
  /// (<= 0 or non-finite) falls back to the default 0.01.
  explicit JetDifferentiator(Scalar epsilon) noexcept {
    if (set_epsilon(epsilon) != Status::ok) set_epsilon(default_epsilon());
    reset(Scalar(0));
  }

  /// Change epsilon, keeping the current jet estimate. Returns Status::non_finite (and keeps
  /// the old value) for epsilon <= 0 or non-finite.
  Status set_epsilon(Scalar epsilon) noexcept {
    if (!is_finite(epsilon) || !(epsilon > Scalar(0))) return Status::non_finite;
    const Jet current = jet_unscaled_or_zero();
    epsilon_ = epsilon;
    Scalar s = Scalar(1);
    for (int i = 0; i <= K; ++i) {
      scale_(i) = s;  // epsilon^i
      s *= epsilon;
    }
    eta_ = current.cwiseProduct(scale_);
    cached_dt_ = Scalar(-1);  // invalidate Phi
    return Status::ok;
  }

  Scalar epsilon() const noexcept { return epsilon_; }

  static constexpr Scalar default_epsilon() noexcept { return Scalar(1) / Scalar(100); }

  /// Start from (y0, 0, ..., 0); see "Start-up transient" above.
  void reset(Scalar y0) noexcept {
    eta_.setZero();
    eta_(0) = y0;
    y_prev_ = y0;
    initialised_ = true;
  }

  /// Start from a known jet (y, y', ..., y^(K)): no start-up transient.
  void reset(const Jet& jet0) noexcept {
    eta_ = jet0.cwiseProduct(scale_);
    y_prev_ = jet0(0);
    initialised_ = true;
  }

  /// Advance by dt > 0 to the new sample y. Returns Status::non_finite, leaving the state
  /// untouched, if dt <= 0 or dt, y are not finite. The step is the C99 kernel
  /// obsynth_jet_update (runtime/obsynth/c/kernels.h), as in the C back end's observers.
  Status update(Scalar dt, Scalar y) noexcept {
    static_assert(std::is_same<Scalar, float>::value || std::is_same<Scalar, double>::value,
                  "JetDifferentiator: float or double");
    Scalar work[3 * (K + 1) * (K + 1) + 2 * (K + 1)];
    return c::jet_update(eta_.data(), phi_, &cached_dt_, &y_prev_, K, epsilon_, dt, y, work)
               ? Status::ok
               : Status::non_finite;
  }

  /// Estimate of y^(k), 0 <= k <= K; quiet NaN for k out of range.
  Scalar derivative(int k) const noexcept {
    if (k < 0 || k > K) return std::numeric_limits<Scalar>::quiet_NaN();
    return eta_(k) / scale_(k);
  }

  /// (y, y', ..., y^(K)) estimate.
  Jet jet() const noexcept { return eta_.cwiseQuotient(scale_); }

  /// Transition matrix Phi(dt/epsilon) of the last update (scaled coordinates); for tests.
  TransitionMatrix transition() const noexcept {
    TransitionMatrix P;
    for (int r = 0; r <= K; ++r)
      for (int c = 0; c <= K; ++c) P(r, c) = phi_[r * (K + 1) + c];
    return P;
  }

 private:
  Jet jet_unscaled_or_zero() const noexcept {
    if (!initialised_) return Jet::Zero();
    return eta_.cwiseQuotient(scale_);
  }

  Jet eta_ = Jet::Zero();               // scaled jet: eta_i = epsilon^i * (estimate of y^(i))
  Jet scale_ = Jet::Ones();             // epsilon^i
  Scalar phi_[(K + 1) * (K + 1)] = {};  // Phi of cached_dt_, row-major (the kernel's layout)
  Scalar epsilon_ = default_epsilon();
  Scalar cached_dt_ = Scalar(-1);
  Scalar y_prev_ = Scalar(0);
  bool initialised_ = false;
};

}  // namespace obsynth
