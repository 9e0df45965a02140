// SPDX-License-Identifier: MIT
// Copyright (c) obsynth authors
//
// Hand-written reference implementation of the canonical-form Luenberger observer for the
// seed 003 worked example (design.md section 1). It is what an expert would write by hand
// with fixed-size Eigen, and serves as the baseline that generated observers are compared
// against (accuracy, speed, code size, stack).
//
// Model:  x' = f(x) + g(x,u),  y = h(x),  with
//   f = [-x2, -x1*x2],  g = [(1+x1)*u, u],  h = x1.
// Diffeomorphism (T(0) = 0):     z = T(x)     = [x1^2/2 - x2, x1]
//                                x = T^-1(z)  = [z2, -z1 + z2^2/2]
// Canonical form (output last, ones on the subdiagonal):
//   z1' = l1(u,y),  z2' = z1 + l2(u,y),  y = z2,
//   l = [(y^2 + y - 1)*u,  -y^2/2 + (1 + y)*u].
// Observer:  zh' = A zh + l(u,y) + K (y - zh2),  A = [[0,0],[1,0]],  K = (c0, c1)
// for the error polynomial s^2 + c1 s + c0, so that e = zh - z obeys e' = (A - K e2^T) e
// exactly, with eigenvalues at the chosen poles. Estimate xh = T^-1(zh).
//
// Discretisation: one classical RK4 step per call with u and y held constant over the step
// (zero-order hold). With u, y frozen the right-hand side is affine in zh,
//   zh' = Acl zh + b,  Acl = [[0, -c0], [1, -c1]],  b = l(u,y) + K y,
// so b is evaluated once per step and each RK4 stage costs two multiply-adds per component.
//
// Conforms to the obsynth observer interface (runtime/obsynth/observer.hpp).
#pragma once

#include "obsynth/eigen.hpp"
#include "obsynth/integrators.hpp"
#include "obsynth/numeric.hpp"
#include "obsynth/status.hpp"

namespace handwritten::seed003 {

template <class Scalar_>
class CanonicalObserver {
 public:
  using Scalar = Scalar_;
  static constexpr int n = 2;
  static constexpr int m = 1;
  static constexpr int p = 1;
  using State = Eigen::Matrix<Scalar, n, 1>;
  using Input = Eigen::Matrix<Scalar, m, 1>;
  using Output = Eigen::Matrix<Scalar, p, 1>;
  using Z = Eigen::Matrix<Scalar, n, 1>;  ///< canonical coordinates

  /// Poles at -2 and -3: s^2 + 5 s + 6.
  CanonicalObserver() noexcept : CanonicalObserver(Scalar(-2), Scalar(-3)) {}

  /// Real poles pole1, pole2 (negative for convergence): s^2 + c1 s + c0 = (s - pole1)(s - pole2).
  CanonicalObserver(Scalar pole1, Scalar pole2) noexcept
      : c0_(pole1 * pole2), c1_(-(pole1 + pole2)) {
    reset_z(Z::Zero());
  }

  /// Gains K = (c0, c1) of the error polynomial s^2 + c1 s + c0.
  Scalar c0() const noexcept { return c0_; }
  Scalar c1() const noexcept { return c1_; }

  /// Start from the estimate xh0 (zh0 = T(xh0)).
  void reset(const State& xh0) noexcept {
    zh_ = T(xh0);
    xh_ = xh0;
    status_ = obsynth::Status::ok;
  }

  /// Start from canonical coordinates zh0 (xh0 = T^-1(zh0)).
  void reset_z(const Z& zh0) noexcept {
    zh_ = zh0;
    xh_ = T_inv(zh0);
    status_ = obsynth::Status::ok;
  }

  /// Advance from t to t + dt with u(t), y(t) held over the step. dt must be > 0.
  /// On a non-finite result (or an invalid dt) the estimate is left unchanged.
  obsynth::Status step(Scalar dt, const Input& u, const Output& y) noexcept {
    if (!obsynth::is_finite(dt) || !(dt > Scalar(0))) {
      return status_ = obsynth::Status::non_finite;
    }
    const Scalar uu = u(0);
    const Scalar yy = y(0);
    // b = l(u, y) + K y, constant over the step
    const Scalar b1 = (yy * yy + yy - Scalar(1)) * uu + c0_ * yy;
    const Scalar b2 = Scalar(-0.5f) * yy * yy + (Scalar(1) + yy) * uu + c1_ * yy;
    const Scalar c0 = c0_;
    const Scalar c1 = c1_;
    Z z = zh_;
    obsynth::rk4_step<Scalar, n>(
        [b1, b2, c0, c1](const Z& zz, Z& dz) noexcept {
          dz(0) = b1 - c0 * zz(1);
          dz(1) = zz(0) + b2 - c1 * zz(1);
        },
        dt, z);
    const State x = T_inv(z);
    if (!obsynth::all_finite(z) || !obsynth::all_finite(x)) {
      return status_ = obsynth::Status::non_finite;
    }
    zh_ = z;
    xh_ = x;
    return status_ = obsynth::Status::ok;
  }

  const State& estimate() const noexcept { return xh_; }
  const Z& z_estimate() const noexcept { return zh_; }
  obsynth::Status status() const noexcept { return status_; }

  /// z = T(x) = [x1^2/2 - x2, x1]
  static Z T(const State& x) noexcept {
    return Z(Scalar(0.5f) * x(0) * x(0) - x(1), x(0));
  }

  /// x = T^-1(z) = [z2, -z1 + z2^2/2]
  static State T_inv(const Z& z) noexcept {
    return State(z(1), Scalar(0.5f) * z(1) * z(1) - z(0));
  }

  /// Output injection l(u, y) = [(y^2 + y - 1) u, -y^2/2 + (1 + y) u]
  static Z l(Scalar u, Scalar y) noexcept {
    return Z((y * y + y - Scalar(1)) * u, Scalar(-0.5f) * y * y + (Scalar(1) + y) * u);
  }

  /// Plant vector field f(x) + g(x, u) (for simulation and tests).
  static State plant(const State& x, Scalar u) noexcept {
    return State(-x(1) + (Scalar(1) + x(0)) * u, -x(0) * x(1) + u);
  }

 private:
  Z zh_ = Z::Zero();
  State xh_ = State::Zero();
  Scalar c0_;
  Scalar c1_;
  obsynth::Status status_ = obsynth::Status::ok;
};

}  // namespace handwritten::seed003
