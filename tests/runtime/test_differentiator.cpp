// SPDX-License-Identifier: MIT
// Copyright (c) obsynth authors
//
// Checks the JetDifferentiator against answers derived independently of the implementation:
// the error transfer functions and the constants documented in differentiator.hpp.
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <limits>
#include <random>

#include "obsynth/differentiator.hpp"

namespace {

using obsynth::JetDifferentiator;
using obsynth::Status;

double binom(int n, int k) {
  double r = 1.0;
  for (int i = 1; i <= k; ++i) r = r * (n - k + i) / i;
  return r;
}

// Steady-state amplitude of the error of derivative k for y = A sin(w t):
// e_k = -P_k(s) / (s + 1/eps)^(K+1) y^(K+1),  P_k(s) = sum_{j<=k} C(K+1, j) eps^-j s^(k-j).
double sine_error_amplitude(int K, int k, double eps, double A, double w) {
  const std::complex<double> s(0.0, w);
  const double lambda = 1.0 / eps;
  std::complex<double> P = 0.0;
  for (int j = 0; j <= k; ++j) P += binom(K + 1, j) * std::pow(lambda, j) * std::pow(s, k - j);
  return std::abs(P / std::pow(s + lambda, K + 1)) * A * std::pow(w, K + 1);
}

// Documented constants (differentiator.hpp): L1 norm G_k and L2 norm N_k of the noise filters.
constexpr double kG2[3] = {1.4601, 1.7507, 0.6200};     // K = 2
constexpr double kN2sq[3] = {33.0 / 16, 7.0 / 4, 3.0 / 16};  // K = 2, N_k^2

template <int K, class Scalar>
void check_sine(double eps, double tol_rel, double tol_abs) {
  const double A = 1.5;
  const double w = 3.0;
  const double dt = 1e-3;
  JetDifferentiator<Scalar, K> d(static_cast<Scalar>(eps));
  d.reset(Scalar(0));
  double max_err[K + 1] = {};
  const int steps = 5000;
  for (int i = 1; i <= steps; ++i) {
    const double t = i * dt;
    ASSERT_EQ(d.update(static_cast<Scalar>(dt), static_cast<Scalar>(A * std::sin(w * t))),
              Status::ok);
    if (t < 1.0) continue;  // > 20 eps: start-up transient below 1e-6
    for (int k = 0; k <= K; ++k) {
      // k-th derivative of A sin(w t) = A w^k sin(w t + k pi/2)
      const double exact = A * std::pow(w, k) * std::sin(w * t + k * M_PI / 2);
      max_err[k] = std::max(max_err[k], std::abs(static_cast<double>(d.derivative(k)) - exact));
    }
  }
  for (int k = 0; k <= K; ++k) {
    const double expected = sine_error_amplitude(K, k, eps, A, w);
    const double bound = binom(K + 1, k) * std::pow(eps, K + 1 - k) * A * std::pow(w, K + 1);
    EXPECT_NEAR(max_err[k], expected, tol_rel * expected + tol_abs) << "k = " << k;
    EXPECT_LE(max_err[k], bound * (1.0 + tol_rel) + tol_abs) << "k = " << k;
    EXPECT_LT(expected, bound) << "k = " << k;
  }
}

TEST(JetDifferentiator, SineErrorMatchesTransferFunctionK1) { check_sine<1, double>(0.01, 0.01, 1e-7); }
TEST(JetDifferentiator, SineErrorMatchesTransferFunctionK2) { check_sine<2, double>(0.02, 0.01, 2e-6); }
TEST(JetDifferentiator, SineErrorMatchesTransferFunctionK3) { check_sine<3, double>(0.05, 0.01, 1e-6); }
TEST(JetDifferentiator, SineErrorFloat) { check_sine<2, float>(0.02, 0.02, 2e-5); }

// y^(K+1) constant: e_k = -C(K+1, k) eps^(K+1-k) y^(K+1) exactly (up to the first-order-hold
// error ~ dt^2 y'' / 12 in e_0).
template <int K>
void check_polynomial_bias(double eps) {
  const double c = 2.0;  // y = c t^(K+1) / (K+1)!
  const double dt = 1e-3;
  double fact = 1.0;
  for (int i = 2; i <= K + 1; ++i) fact *= i;
  JetDifferentiator<double, K> d(eps);
  d.reset(0.0);
  const int steps = static_cast<int>(30 * eps / dt) + 100;
  double t = 0.0;
  for (int i = 1; i <= steps; ++i) {
    t = i * dt;
    d.update(dt, c * std::pow(t, K + 1) / fact);
  }
  for (int k = 0; k <= K; ++k) {
    double fk = 1.0;  // (K+1-k)!
    for (int i = 2; i <= K + 1 - k; ++i) fk *= i;
    const double exact = c * std::pow(t, K + 1 - k) / fk;
    const double expected_err = -binom(K + 1, k) * std::pow(eps, K + 1 - k) * c;
    // FOH: |y_FOH - y| <= dt^2 |y''| / 8 passes with gain <= G_k / eps^k; y'' ~ c t^(K-1).
    const double foh = 2.0 * dt * dt * c * std::pow(t, K - 1) / 8 / std::pow(eps, k);
    EXPECT_NEAR(d.derivative(k) - exact, expected_err, 1e-9 + foh) << "K = " << K << " k = " << k;
  }
}

TEST(JetDifferentiator, PolynomialBiasK1) { check_polynomial_bias<1>(0.05); }
TEST(JetDifferentiator, PolynomialBiasK2) { check_polynomial_bias<2>(0.05); }
TEST(JetDifferentiator, PolynomialBiasK3) { check_polynomial_bias<3>(0.1); }

// A ramp is reproduced exactly for every dt (the first-order hold is exact), even irregular.
TEST(JetDifferentiator, RampIsExactForIrregularSampling) {
  JetDifferentiator<double, 3> seeded(0.02);
  JetDifferentiator<double, 3> unseeded(0.02);
  seeded.reset(JetDifferentiator<double, 3>::Jet(2.0, 3.0, 0.0, 0.0));
  unseeded.reset(2.0);
  const double dts[3] = {0.3e-3, 1.7e-3, 1e-3};
  double t = 0.0;
  for (int i = 0; i < 3000; ++i) {
    const double dt = dts[i % 3];
    t += dt;
    ASSERT_EQ(seeded.update(dt, 2.0 + 3.0 * t), Status::ok);
    unseeded.update(dt, 2.0 + 3.0 * t);
    const auto j = seeded.jet();
    ASSERT_NEAR(j(0), 2.0 + 3.0 * t, 1e-12);
    ASSERT_NEAR(j(1), 3.0, 1e-10);
    ASSERT_NEAR(j(2), 0.0, 1e-8);
    ASSERT_NEAR(j(3), 0.0, 1e-6);
  }
  const auto j = unseeded.jet();  // t = 3 s = 150 eps after reset
  EXPECT_NEAR(j(1), 3.0, 1e-9);
  EXPECT_NEAR(j(2), 0.0, 1e-7);
  EXPECT_NEAR(j(3), 0.0, 1e-5);
}

// Degree <= K: only the first-order-hold error remains, bounded by G_k dt^2 M_2 / (8 eps^k).
TEST(JetDifferentiator, QuadraticOnlyHasSamplingError) {
  const double eps = 0.02;
  const double dt = 1e-3;
  JetDifferentiator<double, 2> d(eps);
  d.reset(JetDifferentiator<double, 2>::Jet(1.0, 2.0, -6.0));  // y = 1 + 2 t - 3 t^2
  double max_err[3] = {};
  for (int i = 1; i <= 2000; ++i) {
    const double t = i * dt;
    d.update(dt, 1.0 + 2.0 * t - 3.0 * t * t);
    const double exact[3] = {1.0 + 2.0 * t - 3.0 * t * t, 2.0 - 6.0 * t, -6.0};
    for (int k = 0; k < 3; ++k)
      max_err[k] = std::max(max_err[k], std::abs(d.derivative(k) - exact[k]));
  }
  for (int k = 0; k < 3; ++k) {
    const double bound = kG2[k] * dt * dt * 6.0 / 8.0 / std::pow(eps, k);
    EXPECT_LE(max_err[k], bound) << "k = " << k;
  }
  // The filter sees y_FOH - y, whose mean over a step is dt^2 y''/12: e_0 -> dt^2 y''/12.
  const double t_end = 2.0;
  const double e0 = d.derivative(0) - (1.0 + 2.0 * t_end - 3.0 * t_end * t_end);
  EXPECT_NEAR(e0, dt * dt * (-6.0) / 12.0, 0.02 * dt * dt * 6.0 / 12.0);
}

// White sampled noise: std(e_k) ~= N_k sigma sqrt(dt/eps) eps^-k, and halving eps multiplies
// it by 2^(k + 1/2).
TEST(JetDifferentiator, WhiteNoiseAmplification) {
  const double sigma = 1e-3;
  const double dt = 1e-3;
  const double eps_values[2] = {0.05, 0.1};
  double measured[2][3] = {};
  for (int e = 0; e < 2; ++e) {
    const double eps = eps_values[e];
    std::mt19937_64 rng(12345u);  // same noise for both epsilons (tighter ratio estimate)
    std::normal_distribution<double> noise(0.0, sigma);
    JetDifferentiator<double, 2> d(eps);
    d.reset(0.0);
    double sum2[3] = {};
    long count = 0;
    const int steps = 100000;  // 100 s = 1000-2000 filter time constants: ~2-3 % sampling error
    for (int i = 1; i <= steps; ++i) {
      d.update(dt, noise(rng));
      if (i * dt < 30 * eps) continue;
      for (int k = 0; k < 3; ++k) sum2[k] += d.derivative(k) * d.derivative(k);
      ++count;
    }
    for (int k = 0; k < 3; ++k) {
      measured[e][k] = std::sqrt(sum2[k] / static_cast<double>(count));
      const double predicted = std::sqrt(kN2sq[k]) * sigma * std::sqrt(dt / eps) / std::pow(eps, k);
      EXPECT_NEAR(measured[e][k], predicted, 0.06 * predicted) << "eps = " << eps << " k = " << k;
    }
  }
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(measured[0][k] / measured[1][k], std::pow(2.0, k + 0.5),
                0.06 * std::pow(2.0, k + 0.5))
        << "k = " << k;
  }
}

// Bounded noise |v| <= delta never produces more than G_k delta / eps^k.
TEST(JetDifferentiator, BoundedNoiseStaysWithinWorstCaseBound) {
  const double delta = 1e-3;
  const double eps = 0.05;
  const double dt = 1e-3;
  std::mt19937_64 rng(7u);
  std::uniform_real_distribution<double> noise(-delta, delta);
  JetDifferentiator<double, 2> d(eps);
  d.reset(0.0);
  double max_err[3] = {};
  for (int i = 1; i <= 50000; ++i) {
    d.update(dt, noise(rng));
    for (int k = 0; k < 3; ++k) max_err[k] = std::max(max_err[k], std::abs(d.derivative(k)));
  }
  for (int k = 0; k < 3; ++k) {
    EXPECT_LE(max_err[k], kG2[k] * delta / std::pow(eps, k)) << "k = " << k;
    EXPECT_GT(max_err[k], 0.1 * kG2[k] * delta / std::pow(eps, k)) << "k = " << k;
  }
}

// Start-up: the difference between a filter reset with zero derivatives and one seeded with
// the exact jet decays as Phi(t/eps); documented: ||Phi(tau)||_inf < 1e-3 for tau >= 13.07 and
// < 1e-6 for tau >= 20.95 (K = 2), in scaled coordinates eta_i = eps^i xi_i.
TEST(JetDifferentiator, StartupTransientMatchesDocumentedSettlingTimes) {
  const double eps = 0.05;
  const double dt = 1e-4;
  auto y = [](double t) { return std::sin(2.0 * t) + 0.5 * t; };
  using D = JetDifferentiator<double, 2>;
  D a(eps);
  D b(eps);
  a.reset(y(0.0));
  b.reset(D::Jet(0.0, 2.0 + 0.5, 0.0));
  const D::Jet scale(1.0, eps, eps * eps);
  const double d0 = (a.jet() - b.jet()).cwiseProduct(scale).lpNorm<Eigen::Infinity>();
  double at_13 = -1.0;
  double at_21 = -1.0;
  for (int i = 1; i <= 12000; ++i) {
    a.update(dt, y(i * dt));
    b.update(dt, y(i * dt));
    const double tau = i * dt / eps;
    const double diff = (a.jet() - b.jet()).cwiseProduct(scale).lpNorm<Eigen::Infinity>();
    if (at_13 < 0 && tau >= 13.1) at_13 = diff;
    if (at_21 < 0 && tau >= 21.0) at_21 = diff;
  }
  EXPECT_LE(at_13, 1e-3 * d0);
  EXPECT_LE(at_21, 1e-6 * d0);
  EXPECT_GT(at_13, 0.0);
}

TEST(JetDifferentiator, TransitionMatrixIsExactExponential) {
  // K = 1: M = [[-2, 1], [-1, 0]] = -I + N, N = [[-1, 1], [-1, 1]] (N^2 = 0), so
  // exp(M h) = e^{-h} (I + h N).
  JetDifferentiator<double, 1> d(0.1);
  d.reset(0.0);
  d.update(0.05, 1.0);  // h = 0.5
  Eigen::Matrix2d expected;
  const double h = 0.5;
  expected << 1.0 - h, h, -h, 1.0 + h;
  expected *= std::exp(-h);
  EXPECT_LT((d.transition() - expected).norm(), 1e-15);
}

TEST(JetDifferentiator, InvalidInputsAreRejected) {
  JetDifferentiator<double, 2> d(0.05);
  d.reset(JetDifferentiator<double, 2>::Jet(1.0, 2.0, 3.0));
  const auto before = d.jet();
  EXPECT_EQ(d.update(0.0, 1.0), Status::non_finite);
  EXPECT_EQ(d.update(-1e-3, 1.0), Status::non_finite);
  EXPECT_EQ(d.update(1e-3, std::numeric_limits<double>::quiet_NaN()), Status::non_finite);
  EXPECT_EQ(d.update(std::numeric_limits<double>::infinity(), 1.0), Status::non_finite);
  EXPECT_EQ(d.jet(), before);
  EXPECT_TRUE(std::isnan(d.derivative(-1)));
  EXPECT_TRUE(std::isnan(d.derivative(3)));
  EXPECT_EQ(d.set_epsilon(0.0), Status::non_finite);
  EXPECT_EQ(d.set_epsilon(-1.0), Status::non_finite);
  EXPECT_EQ(d.epsilon(), 0.05);
  // Changing epsilon keeps the current jet estimate.
  EXPECT_EQ(d.set_epsilon(0.2), Status::ok);
  EXPECT_LT((d.jet() - before).norm(), 1e-14);
  // An invalid constructor argument falls back to the default.
  JetDifferentiator<float, 1> f(-1.0f);
  EXPECT_EQ(f.epsilon(), (JetDifferentiator<float, 1>::default_epsilon()));
}

TEST(JetDifferentiator, HugeStepDoesNotProduceNaN) {
  JetDifferentiator<float, 3> d(1e-3f);
  d.reset(0.0f);
  EXPECT_EQ(d.update(10.0f, 5.0f), Status::ok);  // h = 1e4
  EXPECT_FLOAT_EQ(d.derivative(0), 5.0f);
  EXPECT_FLOAT_EQ(d.derivative(1), 0.5f);
  EXPECT_FLOAT_EQ(d.derivative(2), 0.0f);
}

TEST(JetDifferentiator, OrderZeroIsTheSample) {
  JetDifferentiator<double, 0> d;
  d.reset(1.0);
  d.update(1e-3, 4.25);
  EXPECT_EQ(d.derivative(0), 4.25);
  EXPECT_EQ(d.jet()(0), 4.25);
}

}  // namespace
