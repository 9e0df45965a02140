// SPDX-License-Identifier: MIT
// Copyright (c) obsynth authors
//
// The expert hand-written step of the seed 003 canonical observer (issue 7's reference): the
// same observer as handwritten_seed003.hpp, but with the RK4 step of the linear z dynamics
// folded into two precomputed 2x2 matrices. With u, y held over a step,
//   zh' = Acl zh + b,  Acl = [[0, -c0], [1, -c1]],  b = l(u, y) + K y,
// and one RK4 step of a linear system is exactly zh <- P zh + Q b with
//   P = I + hA + (hA)^2/2 + (hA)^3/6 + (hA)^4/24,  Q = h (I + hA/2 + (hA)^2/6 + (hA)^3/24).
// P and Q are recomputed only when dt changes; a step is then b, two 2x2 products, T^-1 and
// the finiteness checks. Conforms to the obsynth observer interface.
#pragma once

#include "obsynth/eigen.hpp"
#include "obsynth/numeric.hpp"
#include "obsynth/status.hpp"

namespace handwritten::seed003 {

template <class Scalar_>
class ExpertObserver {
 public:
  using Scalar = Scalar_;
  static constexpr int n = 2;
  static constexpr int m = 1;
  static constexpr int p = 1;
  using State = Eigen::Matrix<Scalar, n, 1>;
  using Input = Eigen::Matrix<Scalar, m, 1>;
  using Output = Eigen::Matrix<Scalar, p, 1>;

  ExpertObserver(Scalar pole1, Scalar pole2) noexcept : c0_(pole1 * pole2), c1_(-(pole1 + pole2)) {}

  void reset(const State& xh0) noexcept {
    z1_ = Scalar(0.5) * xh0(0) * xh0(0) - xh0(1);
    z2_ = xh0(0);
    xh_ = xh0;
    status_ = obsynth::Status::ok;
  }

  obsynth::Status step(Scalar dt, const Input& u, const Output& y) noexcept {
    if (dt != dt_ && !fold(dt)) return status_ = obsynth::Status::non_finite;
    const Scalar uu = u(0), yy = y(0);
    const Scalar b1 = (yy * yy + yy - Scalar(1)) * uu + c0_ * yy;
    const Scalar b2 = Scalar(-0.5) * yy * yy + (Scalar(1) + yy) * uu + c1_ * yy;
    const Scalar z1 = p11_ * z1_ + p12_ * z2_ + q11_ * b1 + q12_ * b2;
    const Scalar z2 = p21_ * z1_ + p22_ * z2_ + q21_ * b1 + q22_ * b2;
    const Scalar x2 = Scalar(0.5) * z2 * z2 - z1;
    if (!obsynth::is_finite(z1) || !obsynth::is_finite(z2) || !obsynth::is_finite(x2))
      return status_ = obsynth::Status::non_finite;
    z1_ = z1;
    z2_ = z2;
    xh_(0) = z2;
    xh_(1) = x2;
    return status_ = obsynth::Status::ok;
  }

  const State& estimate() const noexcept { return xh_; }
  obsynth::Status status() const noexcept { return status_; }

 private:
  bool fold(Scalar h) noexcept {
    using M = Eigen::Matrix<Scalar, 2, 2>;
    M A;
    A << Scalar(0), -c0_, Scalar(1), -c1_;
    const M hA = h * A, hA2 = hA * hA, hA3 = hA2 * hA, hA4 = hA3 * hA;
    const M I = M::Identity();
    const M P = I + hA + hA2 / Scalar(2) + hA3 / Scalar(6) + hA4 / Scalar(24);
    const M Q = h * (I + hA / Scalar(2) + hA2 / Scalar(6) + hA3 / Scalar(24));
    if (!obsynth::all_finite(P) || !obsynth::all_finite(Q)) return false;
    p11_ = P(0, 0), p12_ = P(0, 1), p21_ = P(1, 0), p22_ = P(1, 1);
    q11_ = Q(0, 0), q12_ = Q(0, 1), q21_ = Q(1, 0), q22_ = Q(1, 1);
    dt_ = h;
    return true;
  }

  Scalar c0_, c1_;
  Scalar p11_{}, p12_{}, p21_{}, p22_{}, q11_{}, q12_{}, q21_{}, q22_{};
  Scalar dt_ = Scalar(0);
  Scalar z1_ = Scalar(0), z2_ = Scalar(0);
  State xh_ = State::Zero();
  obsynth::Status status_ = obsynth::Status::ok;
};

}  // namespace handwritten::seed003
