// SPDX-License-Identifier: MIT
// Copyright (c) obsynth authors
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "obsynth/newton.hpp"

namespace {

using obsynth::Status;
using V1 = Eigen::Matrix<double, 1, 1>;
using M1 = Eigen::Matrix<double, 1, 1>;
using V2 = Eigen::Matrix<double, 2, 1>;
using M2 = Eigen::Matrix<double, 2, 2>;
using V4 = Eigen::Matrix<double, 4, 1>;
using M4 = Eigen::Matrix<double, 4, 4>;

// Seed 003 diffeomorphism (design.md section 1): T = [x1^2/2 - x2, x1],
// T^-1(z) = [z2, -z1 + z2^2/2], frame [tau] = (dT/dx)^-1 = [[0, 1], [-1, x1]].
template <class S>
struct Seed003 {
  using V = Eigen::Matrix<S, 2, 1>;
  using M = Eigen::Matrix<S, 2, 2>;
  static void T(const V& x, V& z) noexcept {
    z(0) = x(0) * x(0) / S(2) - x(1);
    z(1) = x(0);
  }
  static V T_inv(const V& z) noexcept { return V(z(1), -z(0) + z(1) * z(1) / S(2)); }
  static void tau(const V& x, M& t) noexcept { t << S(0), S(1), S(-1), x(0); }
  static void jac(const V& x, M& j) noexcept { j << x(0), S(-1), S(1), S(0); }
};

TEST(Newton, InverseJacobianConvergesOnSeed003) {
  using P = Seed003<double>;
  const V2 z(0.4, -1.3);
  const V2 x_exact = P::T_inv(z);
  V2 x = x_exact + V2(0.05, -0.04);  // previous estimate
  const auto r = obsynth::newton_solve_inverse_jacobian<double, 2>(P::T, P::tau, z, x, 10, 1e-14);
  EXPECT_EQ(r.status, Status::ok);
  EXPECT_LE(r.iterations, 4);
  EXPECT_GE(r.iterations, 1);
  EXPECT_LE(r.residual_norm, 1e-14 * (1.0 + 1.3));
  EXPECT_LT((x - x_exact).lpNorm<Eigen::Infinity>(), 1e-13);
}

TEST(Newton, JacobianVariantConvergesOnSeed003FromFarAway) {
  using P = Seed003<double>;
  const V2 z(-2.0, 3.0);
  const V2 x_exact = P::T_inv(z);
  V2 x(0.5, 0.5);
  const auto r = obsynth::newton_solve_jacobian<double, 2>(P::T, P::jac, z, x, 20, 1e-14);
  EXPECT_EQ(r.status, Status::ok);
  EXPECT_LT((x - x_exact).lpNorm<Eigen::Infinity>(), 1e-13);
}

TEST(Newton, SeedThatAlreadySolvesTakesNoIteration) {
  using P = Seed003<double>;
  const V2 z(0.4, -1.3);
  V2 x = P::T_inv(z);
  const auto r = obsynth::newton_solve_inverse_jacobian<double, 2>(P::T, P::tau, z, x, 10, 1e-12);
  EXPECT_EQ(r.status, Status::ok);
  EXPECT_EQ(r.iterations, 0);
}

// A genuinely nonlinear global diffeomorphism of R^4: T(x) = x + 0.3 tanh(B x) with
// ||B|| small enough that dT/dx = I + 0.3 diag(sech^2(Bx)) B is always invertible.
struct Tanh4 {
  static M4 B() {
    M4 b;
    b << 0.9, -0.4, 0.2, 0.1,  //
        0.3, 0.8, -0.5, 0.0,   //
        -0.2, 0.1, 0.7, 0.4,   //
        0.1, 0.6, -0.3, 0.9;
    return b;
  }
  static void T(const V4& x, V4& z) noexcept { z = x + 0.3 * (B() * x).array().tanh().matrix(); }
  static void jac(const V4& x, M4& j) noexcept {
    const V4 c = (B() * x).array().cosh().matrix();
    j = M4::Identity();
    for (int i = 0; i < 4; ++i) j.row(i) += 0.3 / (c(i) * c(i)) * B().row(i);
  }
  static void inv_jac(const V4& x, M4& t) noexcept {
    M4 j;
    jac(x, j);
    t = j.inverse();
  }
};

TEST(Newton, QuadraticConvergence) {
  const V4 x_exact(0.7, -1.2, 0.4, 2.0);
  V4 z;
  Tanh4::T(x_exact, z);
  const V4 seed = x_exact + V4(0.2, -0.1, 0.15, -0.2);
  double err[5];
  for (int cap = 0; cap < 5; ++cap) {
    V4 x = seed;
    const auto r =
        obsynth::newton_solve_jacobian<double, 4>(Tanh4::T, Tanh4::jac, z, x, cap, 0.0);
    err[cap] = (x - x_exact).norm();
    if (err[cap] > 1e-15) {
      EXPECT_EQ(r.iterations, cap);
    }
  }
  // e_{k+1} <= C e_k^2 with a moderate C (second derivative / first derivative of T).
  for (int k = 0; k < 3; ++k) {
    if (err[k + 1] < 1e-14) break;
    EXPECT_LT(err[k + 1], 1.0 * err[k] * err[k]) << "k = " << k;
  }
  EXPECT_LT(err[4], 1e-14);
}

TEST(Newton, BothVariantsProduceTheSameIterates) {
  const V4 x_exact(-0.3, 0.9, 1.1, -0.6);
  V4 z;
  Tanh4::T(x_exact, z);
  for (int cap = 1; cap <= 3; ++cap) {
    V4 xa = V4::Zero();
    V4 xb = V4::Zero();
    obsynth::newton_solve_inverse_jacobian<double, 4>(Tanh4::T, Tanh4::inv_jac, z, xa, cap, 0.0);
    obsynth::newton_solve_jacobian<double, 4>(Tanh4::T, Tanh4::jac, z, xb, cap, 0.0);
    EXPECT_LT((xa - xb).norm(), 1e-12) << "cap = " << cap;
  }
}

// x^3 = 0 from x = 1: Newton converges only linearly, x_k = (2/3)^k exactly.
TEST(Newton, IterationCapReportsNotConvergedAndKeepsLastIterate) {
  auto T = [](const V1& x, V1& z) noexcept { z(0) = x(0) * x(0) * x(0); };
  auto J = [](const V1& x, M1& j) noexcept { j(0, 0) = 3.0 * x(0) * x(0); };
  auto tau = [](const V1& x, M1& t) noexcept { t(0, 0) = 1.0 / (3.0 * x(0) * x(0)); };
  const V1 z = V1::Zero();
  V1 x = V1::Ones();
  auto r = obsynth::newton_solve_jacobian<double, 1>(T, J, z, x, 5, 1e-12);
  EXPECT_EQ(r.status, Status::newton_not_converged);
  EXPECT_EQ(r.iterations, 5);
  EXPECT_NEAR(x(0), std::pow(2.0 / 3.0, 5), 1e-15);
  EXPECT_NEAR(r.residual_norm, std::pow(2.0 / 3.0, 15), 1e-15);

  x = V1::Ones();
  r = obsynth::newton_solve_inverse_jacobian<double, 1>(T, tau, z, x, 5, 1e-12);
  EXPECT_EQ(r.status, Status::newton_not_converged);
  EXPECT_NEAR(x(0), std::pow(2.0 / 3.0, 5), 1e-15);

  x = V1::Ones();
  r = obsynth::newton_solve_inverse_jacobian<double, 1>(T, tau, z, x, 0, 1e-12);
  EXPECT_EQ(r.status, Status::newton_not_converged);
  EXPECT_EQ(r.iterations, 0);
  EXPECT_EQ(x(0), 1.0);
}

// log(x) = 0 from x = 3: the first step lands at 3 - 3 log 3 < 0, where log is NaN.
TEST(Newton, NonFiniteResidualRestoresLastFiniteIterate) {
  auto T = [](const V1& x, V1& z) noexcept { z(0) = std::log(x(0)); };
  auto tau = [](const V1& x, M1& t) noexcept { t(0, 0) = x(0); };
  auto J = [](const V1& x, M1& j) noexcept { j(0, 0) = 1.0 / x(0); };
  const V1 z = V1::Zero();
  V1 x;
  x << 3.0;
  auto r = obsynth::newton_solve_inverse_jacobian<double, 1>(T, tau, z, x, 10, 1e-12);
  EXPECT_EQ(r.status, Status::non_finite);
  EXPECT_EQ(x(0), 3.0);
  EXPECT_EQ(r.iterations, 1);
  EXPECT_NEAR(r.residual_norm, std::log(3.0), 1e-15);

  x << 3.0;
  r = obsynth::newton_solve_jacobian<double, 1>(T, J, z, x, 10, 1e-12);
  EXPECT_EQ(r.status, Status::non_finite);
  EXPECT_EQ(x(0), 3.0);
}

TEST(Newton, NonFiniteInputsAndJacobians) {
  using P = Seed003<double>;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  V2 x(1.0, 1.0);
  auto r = obsynth::newton_solve_inverse_jacobian<double, 2>(P::T, P::tau, V2(nan, 0.0), x, 10,
                                                             1e-12);
  EXPECT_EQ(r.status, Status::non_finite);
  EXPECT_EQ(r.iterations, 0);
  EXPECT_EQ(x, V2(1.0, 1.0));

  x = V2(inf, 1.0);
  r = obsynth::newton_solve_jacobian<double, 2>(P::T, P::jac, V2(0.0, 0.0), x, 10, 1e-12);
  EXPECT_EQ(r.status, Status::non_finite);

  auto bad_tau = [](const V2&, M2& t) noexcept { t.setConstant(std::nan("")); };
  x = V2(1.0, 1.0);
  r = obsynth::newton_solve_inverse_jacobian<double, 2>(P::T, bad_tau, V2(0.0, 0.0), x, 10,
                                                        1e-12);
  EXPECT_EQ(r.status, Status::non_finite);
  EXPECT_EQ(x, V2(1.0, 1.0));
  EXPECT_TRUE(std::isfinite(r.residual_norm));

  auto bad_jac = [](const V2&, M2& j) noexcept {
    j.setConstant(std::numeric_limits<double>::infinity());
  };
  r = obsynth::newton_solve_jacobian<double, 2>(P::T, bad_jac, V2(0.0, 0.0), x, 10, 1e-12);
  EXPECT_EQ(r.status, Status::non_finite);
  EXPECT_EQ(x, V2(1.0, 1.0));
}

TEST(Newton, SingularJacobian) {
  // T = [x1^2, x2] has dT/dx = diag(2 x1, 1), singular at x1 = 0.
  auto T = [](const V2& x, V2& z) noexcept { z = V2(x(0) * x(0), x(1)); };
  auto J = [](const V2& x, M2& j) noexcept { j << 2.0 * x(0), 0.0, 0.0, 1.0; };
  V2 x(0.0, 1.0);
  const auto r = obsynth::newton_solve_jacobian<double, 2>(T, J, V2(1.0, 1.0), x, 10, 1e-12);
  EXPECT_EQ(r.status, Status::singular);
  EXPECT_EQ(r.iterations, 0);
  EXPECT_EQ(x, V2(0.0, 1.0));
  // Numerically singular too (pivot ratio ~ 1e-17 < 2 eps).
  x = V2(1e-17, 1.0);
  const auto r2 = obsynth::newton_solve_jacobian<double, 2>(T, J, V2(1.0, 1.0), x, 10, 1e-12);
  EXPECT_EQ(r2.status, Status::singular);
}

TEST(Newton, ToleranceIsRelativeToTheSizeOfZ) {
  // Identity map, seed off by 1e-7 relative to |z| = 1e6: |r| = 0.1 <= 1e-6 (1 + 1e6).
  auto T = [](const V1& x, V1& z) noexcept { z = x; };
  auto tau = [](const V1&, M1& t) noexcept { t(0, 0) = 1.0; };
  V1 z;
  z << 1e6;
  V1 x;
  x << 1e6 + 0.1;
  const auto r = obsynth::newton_solve_inverse_jacobian<double, 1>(T, tau, z, x, 0, 1e-6);
  EXPECT_EQ(r.status, Status::ok);
  EXPECT_EQ(r.iterations, 0);
}

TEST(Newton, FloatInstantiation) {
  using P = Seed003<float>;
  using F2 = Eigen::Matrix<float, 2, 1>;
  const F2 z(0.4f, -1.3f);
  const F2 x_exact = P::T_inv(z);
  F2 xa = x_exact + F2(0.1f, 0.1f);
  F2 xb = xa;
  const auto ra = obsynth::newton_solve_inverse_jacobian<float, 2>(P::T, P::tau, z, xa, 10, 1e-6f);
  const auto rb = obsynth::newton_solve_jacobian<float, 2>(P::T, P::jac, z, xb, 10, 1e-6f);
  static_assert(std::is_same_v<decltype(ra.residual_norm), float>);
  EXPECT_EQ(ra.status, Status::ok);
  EXPECT_EQ(rb.status, Status::ok);
  EXPECT_LT((xa - x_exact).lpNorm<Eigen::Infinity>(), 1e-5f);
  EXPECT_LT((xb - x_exact).lpNorm<Eigen::Infinity>(), 1e-5f);
}

}  // namespace
