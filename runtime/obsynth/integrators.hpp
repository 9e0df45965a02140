// SPDX-License-Identifier: MIT
// Copyright (c) obsynth authors
//
// Explicit fixed-step integrators for autonomous systems x' = F(x).
//
// Observers are sampled-data systems: inputs u and measurements y are held constant over a
// step (zero-order hold), so the right-hand side is captured in a callable that closes over
// them:
//
//   auto rhs = [&](const obsynth::Vector<float, 2>& x, obsynth::Vector<float, 2>& dx) noexcept {
//     dx = f(x, u, y);
//   };
//   obsynth::rk4_step(rhs, dt, x);
//
// The callable must have the signature
//   void rhs(const Eigen::Matrix<Scalar, N, 1>& x, Eigen::Matrix<Scalar, N, 1>& dx) noexcept
// and write every component of dx. It is taken by forwarding reference and called directly
// (never through std::function or a function pointer), so the compiler can inline it.
// Stage vectors live on the stack: no heap, no exceptions. dx never aliases x.
//
// Local truncation error per step is O(dt^2) (Euler), O(dt^3) (Heun), O(dt^5) (RK4); the
// global error over a fixed horizon is O(dt), O(dt^2), O(dt^4) respectively.
#pragma once

#include <type_traits>
#include <utility>

#include "obsynth/c_kernels.hpp"
#include "obsynth/eigen.hpp"
#include "obsynth/numeric.hpp"

namespace obsynth {

namespace detail {
template <class Rhs, class Scalar, int N>
constexpr void check_rhs() noexcept {
  static_assert(N > 0, "obsynth integrators need a fixed, positive state dimension");
  static_assert(std::is_invocable_r_v<void, Rhs&, const Eigen::Matrix<Scalar, N, 1>&,
                                      Eigen::Matrix<Scalar, N, 1>&>,
                "rhs must be callable as rhs(const Matrix<Scalar,N,1>& x, "
                "Matrix<Scalar,N,1>& dx)");
  static_assert(std::is_nothrow_invocable_v<Rhs&, const Eigen::Matrix<Scalar, N, 1>&,
                                            Eigen::Matrix<Scalar, N, 1>&>,
                "rhs must be noexcept (declare the lambda or operator() noexcept)");
}
}  // namespace detail

/// Explicit Euler: x <- x + dt F(x). First order.
template <class Scalar, int N, class Rhs>
inline void euler_step(Rhs&& rhs, detail::type_identity_t<Scalar> dt,
                       Eigen::Matrix<Scalar, N, 1>& x) noexcept {
  detail::check_rhs<Rhs, Scalar, N>();
  Eigen::Matrix<Scalar, N, 1> k1;
  rhs(static_cast<const Eigen::Matrix<Scalar, N, 1>&>(x), k1);
  x += dt * k1;
}

/// Heun's method (explicit trapezoidal rule, RK2):
///   k1 = F(x), k2 = F(x + dt k1), x <- x + dt/2 (k1 + k2). Second order.
template <class Scalar, int N, class Rhs>
inline void heun_step(Rhs&& rhs, detail::type_identity_t<Scalar> dt,
                      Eigen::Matrix<Scalar, N, 1>& x) noexcept {
  detail::check_rhs<Rhs, Scalar, N>();
  Eigen::Matrix<Scalar, N, 1> k1;
  Eigen::Matrix<Scalar, N, 1> k2;
  Eigen::Matrix<Scalar, N, 1> xs;
  rhs(static_cast<const Eigen::Matrix<Scalar, N, 1>&>(x), k1);
  xs = x + dt * k1;
  rhs(static_cast<const Eigen::Matrix<Scalar, N, 1>&>(xs), k2);
  x += (dt * Scalar(0.5)) * (k1 + k2);
}

/// Classical fourth-order Runge-Kutta:
///   k1 = F(x), k2 = F(x + dt/2 k1), k3 = F(x + dt/2 k2), k4 = F(x + dt k3),
///   x <- x + dt/6 (k1 + 2 k2 + 2 k3 + k4). Fourth order. The stages are the C kernel
/// obsynth_rk4_stage (as the C back end's and the simulator's RK4).
template <class Scalar, int N, class Rhs>
inline void rk4_step(Rhs&& rhs, detail::type_identity_t<Scalar> dt,
                     Eigen::Matrix<Scalar, N, 1>& x) noexcept {
  detail::check_rhs<Rhs, Scalar, N>();
  using Vec = Eigen::Matrix<Scalar, N, 1>;
  Vec k, acc, t;  // stage derivative, k1 + 2 k2 + 2 k3, stage point
  // Written out stage by stage: each kernel call's stage is then a constant and its switch folds.
  rhs(static_cast<const Vec&>(x), k);
  c::rk4_stage(0, Scalar(dt), N, x.data(), k.data(), acc.data(), t.data());
  rhs(static_cast<const Vec&>(t), k);
  c::rk4_stage(1, Scalar(dt), N, x.data(), k.data(), acc.data(), t.data());
  rhs(static_cast<const Vec&>(t), k);
  c::rk4_stage(2, Scalar(dt), N, x.data(), k.data(), acc.data(), t.data());
  rhs(static_cast<const Vec&>(t), k);
  c::rk4_stage(3, Scalar(dt), N, x.data(), k.data(), acc.data(), x.data());
}

}  // namespace obsynth
