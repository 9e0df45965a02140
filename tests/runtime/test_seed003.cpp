// SPDX-License-Identifier: MIT
// Copyright (c) obsynth authors
//
// The hand-written seed 003 observer (bench/handwritten_seed003.hpp) against the worked
// example of design.md section 1 and against the exact linear error dynamics.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "../../bench/handwritten_seed003.hpp"
#include "obsynth/integrators.hpp"

namespace {

using obsynth::Status;
template <class S>
using Obs = handwritten::seed003::CanonicalObserver<S>;
using V2 = Eigen::Vector2d;
using M2 = Eigen::Matrix2d;

// exp(Acl t) e0 with Acl = [[0, -c0], [1, -c1]] and distinct real eigenvalues l1, l2.
V2 predicted_error(double c0, double c1, double l1, double l2, double t, const V2& e0) {
  M2 A;
  A << 0.0, -c0, 1.0, -c1;
  const M2 I = M2::Identity();
  const M2 E = (std::exp(l1 * t) * (A - l2 * I) - std::exp(l2 * t) * (A - l1 * I)) / (l1 - l2);
  return E * e0;
}

TEST(Seed003, WorkedExampleIdentities) {
  using O = Obs<double>;
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> U(-2.0, 2.0);
  for (int i = 0; i < 100; ++i) {
    const V2 x(U(rng), U(rng));
    const double u = U(rng);
    // T^-1(T(x)) = x
    EXPECT_LT((O::T_inv(O::T(x)) - x).norm(), 1e-14);
    // Canonical form: d/dt T(x) = dT/dx (f + g) = A T(x) + l(u, h(x)), A = [[0,0],[1,0]].
    M2 dT;
    dT << x(0), -1.0, 1.0, 0.0;
    const V2 lhs = dT * O::plant(x, u);
    const V2 z = O::T(x);
    const V2 rhs = V2(0.0, z(0)) + O::l(u, x(0));
    EXPECT_LT((lhs - rhs).norm(), 1e-13);
  }
  // Gains: poles -2, -3 -> s^2 + 5 s + 6 -> K = (c0, c1) = (6, 5).
  O obs;
  EXPECT_EQ(obs.c0(), 6.0);
  EXPECT_EQ(obs.c1(), 5.0);
  // T(0) = 0 and T^-1(0) = 0.
  EXPECT_EQ(O::T(V2::Zero()), V2::Zero());
  EXPECT_EQ(O::T_inv(V2::Zero()), V2::Zero());
}

// At the equilibrium x = (c, 0), u = 0 the measurement is constant, so the zero-order hold is
// exact and the z-error follows exp(Acl t) e0 up to the RK4 truncation error (~dt^4).
TEST(Seed003, ErrorFollowsChosenPolesExactlyAtEquilibrium) {
  using O = Obs<double>;
  const V2 x(1.5, 0.0);
  O obs(-2.0, -3.0);
  obs.reset(V2(-0.7, 0.9));
  const V2 e0 = obs.z_estimate() - O::T(x);
  O::Input u;
  u << 0.0;
  O::Output y;
  y << x(0);
  const double dt = 1e-3;
  for (int k = 1; k <= 3000; ++k) {
    ASSERT_EQ(obs.step(dt, u, y), Status::ok);
    if (k % 500 == 0) {
      const V2 e = obs.z_estimate() - O::T(x);
      const V2 ep = predicted_error(6.0, 5.0, -2.0, -3.0, k * dt, e0);
      EXPECT_LT((e - ep).lpNorm<Eigen::Infinity>(), 1e-11) << "t = " << k * dt;
    }
  }
  EXPECT_LT((obs.estimate() - x).norm(), 0.05);  // e^{-6} scale after 3 s
}

TEST(Seed003, FloatErrorFollowsChosenPoles) {
  using O = Obs<float>;
  const Eigen::Vector2f x(1.5f, 0.0f);
  O obs(-4.0f, -5.0f);
  obs.reset(Eigen::Vector2f(-0.7f, 0.9f));
  const V2 e0 = (obs.z_estimate() - O::T(x)).cast<double>();
  O::Input u;
  u << 0.0f;
  O::Output y;
  y << x(0);
  for (int k = 1; k <= 2000; ++k) {
    ASSERT_EQ(obs.step(1e-3f, u, y), Status::ok);
  }
  const V2 e = (obs.z_estimate() - O::T(x)).cast<double>();
  const V2 ep = predicted_error(20.0, 9.0, -4.0, -5.0, 2.0, e0);
  EXPECT_LT((e - ep).lpNorm<Eigen::Infinity>(), 1e-5);
}

// Closed loop with a moving output: the deviation from the pole prediction is the O(dt) effect
// of holding y over a step, so halving dt halves it.
double closed_loop_deviation(double dt, double t_end, double* final_error) {
  using O = Obs<double>;
  O obs;
  obs.reset_z(V2::Zero());
  V2 x(0.5, -0.3);
  const V2 e0 = obs.z_estimate() - O::T(x);
  const int steps = static_cast<int>(std::lround(t_end / dt));
  double max_dev = 0.0;
  for (int k = 0; k < steps; ++k) {
    const double uk = std::sin(k * dt);
    O::Input u;
    u << uk;
    O::Output y;
    y << x(0);
    obs.step(dt, u, y);
    obsynth::rk4_step<double, 2>([uk](const V2& s, V2& ds) noexcept { ds = O::plant(s, uk); },
                                 dt, x);
    const V2 ep = predicted_error(6.0, 5.0, -2.0, -3.0, (k + 1) * dt, e0);
    max_dev = std::max(max_dev, (obs.z_estimate() - O::T(x) - ep).lpNorm<Eigen::Infinity>());
  }
  *final_error = (obs.estimate() - x).lpNorm<Eigen::Infinity>();
  return max_dev;
}

TEST(Seed003, ClosedLoopSamplingErrorIsFirstOrder) {
  double f1 = 0.0;
  double f2 = 0.0;
  const double d1 = closed_loop_deviation(2e-3, 5.0, &f1);
  const double d2 = closed_loop_deviation(1e-3, 5.0, &f2);
  EXPECT_NEAR(d1 / d2, 2.0, 0.1);
  EXPECT_LT(d2, 50 * 1e-3);
  EXPECT_LT(f2, 5e-3);
}

TEST(Seed003, RejectsNonFiniteAndKeepsEstimate) {
  using O = Obs<double>;
  O obs;
  obs.reset(V2(0.3, 0.2));
  const V2 before = obs.estimate();
  O::Input u;
  u << 0.1;
  O::Output y;
  y << std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(obs.step(1e-3, u, y), Status::non_finite);
  EXPECT_EQ(obs.status(), Status::non_finite);
  EXPECT_EQ(obs.estimate(), before);
  y << 0.3;
  EXPECT_EQ(obs.step(0.0, u, y), Status::non_finite);
  EXPECT_EQ(obs.step(1e-3, u, y), Status::ok);
  EXPECT_EQ(obs.status(), Status::ok);
  obs.reset(V2(0.3, 0.2));
  EXPECT_EQ(obs.status(), Status::ok);
}

}  // namespace
