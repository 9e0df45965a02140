// SPDX-License-Identifier: MIT
// Copyright (c) obsynth authors
#include <gtest/gtest.h>

#include <cmath>

#include "obsynth/integrators.hpp"

namespace {

using V1 = Eigen::Matrix<double, 1, 1>;
using V2 = Eigen::Matrix<double, 2, 1>;
using M2 = Eigen::Matrix<double, 2, 2>;

enum class Method { euler, heun, rk4 };

template <class Scalar, int N, class Rhs>
void step(Method m, Rhs&& rhs, Scalar dt, Eigen::Matrix<Scalar, N, 1>& x) {
  switch (m) {
    case Method::euler:
      obsynth::euler_step<Scalar, N>(rhs, dt, x);
      break;
    case Method::heun:
      obsynth::heun_step<Scalar, N>(rhs, dt, x);
      break;
    case Method::rk4:
      obsynth::rk4_step<Scalar, N>(rhs, dt, x);
      break;
  }
}

// Global error at t = 1 for x' = -x, x(0) = 1 (exact e^-1).
double decay_error(Method m, int steps) {
  auto rhs = [](const V1& x, V1& dx) noexcept { dx = -x; };
  V1 x;
  x << 1.0;
  const double dt = 1.0 / steps;
  for (int i = 0; i < steps; ++i) step(m, rhs, dt, x);
  return std::abs(x(0) - std::exp(-1.0));
}

// Global error after one period of x1' = x2, x2' = -x1 (exact: back to the start).
double oscillator_error(Method m, int steps) {
  auto rhs = [](const V2& x, V2& dx) noexcept {
    dx(0) = x(1);
    dx(1) = -x(0);
  };
  V2 x(1.0, 0.0);
  const double dt = 2.0 * M_PI / steps;
  for (int i = 0; i < steps; ++i) step(m, rhs, dt, x);
  return (x - V2(1.0, 0.0)).norm();
}

double observed_order(double e_coarse, double e_fine) { return std::log2(e_coarse / e_fine); }

TEST(Integrators, Rk4IsFourthOrderOnDecay) {
  const double e1 = decay_error(Method::rk4, 20);
  const double e2 = decay_error(Method::rk4, 40);
  const double e3 = decay_error(Method::rk4, 80);
  // Error ratio when halving dt -> 2^4 = 16.
  EXPECT_NEAR(e1 / e2, 16.0, 1.0);
  EXPECT_NEAR(e2 / e3, 16.0, 0.5);
  EXPECT_NEAR(observed_order(e2, e3), 4.0, 0.05);
  // Leading error term: e^{-h} - R(h) = h^5/120 per step -> global ~ e^-1 h^4 / 120.
  const double h = 1.0 / 80;
  EXPECT_NEAR(e3, std::exp(-1.0) * std::pow(h, 4) / 120.0, 0.05 * e3);
}

TEST(Integrators, Rk4IsFourthOrderOnOscillator) {
  const double e1 = oscillator_error(Method::rk4, 50);
  const double e2 = oscillator_error(Method::rk4, 100);
  const double e3 = oscillator_error(Method::rk4, 200);
  EXPECT_NEAR(e1 / e2, 16.0, 1.0);
  EXPECT_NEAR(e2 / e3, 16.0, 0.5);
}

TEST(Integrators, HeunIsSecondOrder) {
  EXPECT_NEAR(observed_order(decay_error(Method::heun, 40), decay_error(Method::heun, 80)), 2.0,
              0.05);
  const double r = oscillator_error(Method::heun, 200) / oscillator_error(Method::heun, 400);
  EXPECT_NEAR(r, 4.0, 0.2);
}

TEST(Integrators, EulerIsFirstOrder) {
  EXPECT_NEAR(observed_order(decay_error(Method::euler, 200), decay_error(Method::euler, 400)),
              1.0, 0.02);
}

// For x' = A x one step is a known matrix polynomial in hA (the stability function), which
// pins every stage coefficient, not only the order.
TEST(Integrators, OneStepOnLinearSystemIsTheTaylorPolynomial) {
  M2 A;
  A << -0.3, 1.7, -2.1, -0.4;
  const V2 x0(0.8, -1.1);
  const double h = 0.37;
  auto rhs = [&A](const V2& x, V2& dx) noexcept { dx = A * x; };
  const M2 I = M2::Identity();
  const M2 hA = h * A;
  const M2 P1 = I + hA;
  const M2 P2 = P1 + hA * hA / 2.0;
  const M2 P4 = P2 + hA * hA * hA / 6.0 + hA * hA * hA * hA / 24.0;
  V2 x = x0;
  obsynth::euler_step<double, 2>(rhs, h, x);
  EXPECT_LT((x - P1 * x0).norm(), 1e-15);
  x = x0;
  obsynth::heun_step<double, 2>(rhs, h, x);
  EXPECT_LT((x - P2 * x0).norm(), 1e-15);
  x = x0;
  obsynth::rk4_step<double, 2>(rhs, h, x);
  EXPECT_LT((x - P4 * x0).norm(), 1e-15);
}

// Nonlinear, non-autonomous check of the RK4 tableau: x' = t^3 (as a 2-state autonomous system
// with the clock as a state) is integrated exactly by RK4 (quadrature of degree 3 is exact).
TEST(Integrators, Rk4IntegratesCubicQuadratureExactly) {
  auto rhs = [](const V2& s, V2& ds) noexcept {
    ds(0) = s(1) * s(1) * s(1);  // x' = t^3
    ds(1) = 1.0;                 // t' = 1
  };
  V2 s(0.0, 0.0);
  obsynth::rk4_step<double, 2>(rhs, 1.5, s);
  EXPECT_NEAR(s(0), std::pow(1.5, 4) / 4.0, 1e-14);
  EXPECT_NEAR(s(1), 1.5, 1e-15);
}

struct CountingRhs {
  int calls = 0;
  void operator()(const V1& x, V1& dx) noexcept {
    ++calls;
    dx = -x;
  }
};

TEST(Integrators, RhsEvaluationCount) {
  V1 x;
  x << 1.0;
  CountingRhs c;
  obsynth::euler_step<double, 1>(c, 0.1, x);
  EXPECT_EQ(c.calls, 1);
  c.calls = 0;
  obsynth::heun_step<double, 1>(c, 0.1, x);
  EXPECT_EQ(c.calls, 2);
  c.calls = 0;
  obsynth::rk4_step<double, 1>(c, 0.1, x);
  EXPECT_EQ(c.calls, 4);
}

TEST(Integrators, AcceptsRvalueAndConstCallables) {
  struct ConstRhs {
    double a;
    void operator()(const V1& x, V1& dx) const noexcept { dx = a * x; }
  };
  V1 x;
  x << 1.0;
  obsynth::rk4_step<double, 1>(ConstRhs{-1.0}, 0.1, x);  // rvalue
  const ConstRhs c{-1.0};
  obsynth::rk4_step<double, 1>(c, 0.1, x);  // const lvalue
  EXPECT_NEAR(x(0), std::exp(-0.2), 1e-6);  // 2 steps, local error ~ h^5/120
}

TEST(Integrators, FloatInstantiation) {
  using F2 = Eigen::Matrix<float, 2, 1>;
  auto rhs = [](const F2& x, F2& dx) noexcept {
    dx(0) = x(1);
    dx(1) = -x(0);
  };
  F2 x(1.0f, 0.0f);
  const int steps = 100;
  const float dt = 6.2831853f / static_cast<float>(steps);
  for (int i = 0; i < steps; ++i) obsynth::rk4_step<float, 2>(rhs, dt, x);
  // Truncation ~ 2 pi dt^4 / 120 ~ 1e-6 plus float rounding over 100 steps.
  EXPECT_LT((x - F2(1.0f, 0.0f)).norm(), 2e-5f);
  // dt is a non-deduced parameter: Scalar comes from the state alone, so an int or a double
  // argument converts instead of breaking deduction (-Wconversion still flags lossy ones).
  obsynth::rk4_step(rhs, 1, x);
  static_assert(std::is_same_v<decltype(x)::Scalar, float>);
}

}  // namespace
