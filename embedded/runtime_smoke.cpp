// SPDX-License-Identifier: MIT
// Copyright (c) obsynth authors
//
// Cortex-M4F smoke test of every runtime header (embedded/run-qemu.sh compiles it with
// -Werror -Wconversion -Wdouble-promotion): integrators, both Newton variants, the jet
// differentiator and the observer trait, in float (hardware FPU) and double (soft-float).
// Exit status 0 when every result is within its tolerance.
#include <cmath>
#include <cstdio>

#include "obsynth/differentiator.hpp"
#include "obsynth/integrators.hpp"
#include "obsynth/newton.hpp"
#include "obsynth/numeric.hpp"
#include "obsynth/observer.hpp"
#include "obsynth/status.hpp"

namespace {

int failures = 0;

void expect(bool cond, const char* what, double value, double bound) {
  std::printf("%-44s %.3e (bound %.1e) %s\n", what, value, bound, cond ? "ok" : "FAIL");
  if (!cond) ++failures;
}

template <class Scalar>
void run(const char* name) {
  using V2 = obsynth::Vector<Scalar, 2>;
  using M2 = obsynth::Matrix<Scalar, 2, 2>;
  const bool is_float = sizeof(Scalar) == 4;
  std::printf("-- %s\n", name);

  // RK4 on the harmonic oscillator, one period, two step sizes: error ratio ~ 16.
  auto osc = [](const V2& x, V2& dx) noexcept {
    dx(0) = x(1);
    dx(1) = -x(0);
  };
  Scalar err[2];
  for (int r = 0; r < 2; ++r) {
    const int steps = r == 0 ? 20 : 40;
    const Scalar dt = Scalar(6.283185307179586) / static_cast<Scalar>(steps);
    V2 x(Scalar(1), Scalar(0));
    for (int i = 0; i < steps; ++i) obsynth::rk4_step<Scalar, 2>(osc, dt, x);
    err[r] = obsynth::inf_norm(x - V2(Scalar(1), Scalar(0)));
  }
  const double ratio = static_cast<double>(err[0] / err[1]);
  expect(std::fabs(ratio - 16.0) < 1.5, "rk4 error ratio (dt halved), ~16", ratio, 16.0);

  V2 xh(Scalar(1), Scalar(0));
  const Scalar hdt = Scalar(6.283185307179586) / Scalar(400);
  for (int i = 0; i < 400; ++i) obsynth::heun_step<Scalar, 2>(osc, hdt, xh);
  const Scalar heun_err = obsynth::inf_norm(xh - V2(Scalar(1), Scalar(0)));
  // Heun: phase error ~ 2 pi dt^2 / 6 = 2.6e-4 after one period
  expect(heun_err < Scalar(4e-4f), "heun error, 400 steps (~2.6e-4)", static_cast<double>(heun_err), 4e-4);

  // Newton on the seed 003 diffeomorphism T = [x1^2/2 - x2, x1].
  auto T = [](const V2& x, V2& z) noexcept {
    z(0) = x(0) * x(0) / Scalar(2) - x(1);
    z(1) = x(0);
  };
  auto tau = [](const V2& x, M2& t) noexcept { t << Scalar(0), Scalar(1), Scalar(-1), x(0); };
  auto jac = [](const V2& x, M2& j) noexcept { j << x(0), Scalar(-1), Scalar(1), Scalar(0); };
  const V2 z(Scalar(0.4f), Scalar(-1.3f));
  const V2 x_exact(z(1), -z(0) + z(1) * z(1) / Scalar(2));
  const Scalar tol = is_float ? Scalar(1e-6f) : Scalar(1e-13);
  V2 xa(Scalar(0), Scalar(0));
  const auto ra = obsynth::newton_solve_inverse_jacobian<Scalar, 2>(T, tau, z, xa, 10, tol);
  V2 xb(Scalar(0), Scalar(0));
  const auto rb = obsynth::newton_solve_jacobian<Scalar, 2>(T, jac, z, xb, 10, tol);
  const double newton_err =
      static_cast<double>(obsynth::inf_norm(xa - x_exact) + obsynth::inf_norm(xb - x_exact));
  expect(ra.status == obsynth::Status::ok && rb.status == obsynth::Status::ok,
         "newton status ok (both variants), iterations", ra.iterations + rb.iterations, 20);
  expect(newton_err < (is_float ? 1e-5 : 1e-12), "newton |x - x_exact|", newton_err,
         is_float ? 1e-5 : 1e-12);
  V2 xs(Scalar(0), Scalar(1));
  auto J0 = [](const V2& x, M2& j) noexcept { j << Scalar(2) * x(0), Scalar(0), Scalar(0), Scalar(1); };
  auto T0 = [](const V2& x, V2& zz) noexcept { zz = V2(x(0) * x(0), x(1)); };
  const auto rs = obsynth::newton_solve_jacobian<Scalar, 2>(T0, J0, V2(Scalar(1), Scalar(1)),
                                                            xs, 10, tol);
  expect(rs.status == obsynth::Status::singular, "newton reports singular", 0.0, 0.0);

  // Differentiator on y = sin(3t): steady error of y' vs |P_1(jw)/(jw+1/eps)^3| A w^3.
  const Scalar eps = Scalar(0.02f);
  obsynth::JetDifferentiator<Scalar, 2> d(eps);
  d.reset(Scalar(0));
  const Scalar dt = Scalar(1e-3f);
  Scalar max_e1 = Scalar(0);
  for (int i = 1; i <= 3000; ++i) {
    const Scalar t = static_cast<Scalar>(i) * dt;
    d.update(dt, std::sin(Scalar(3) * t));
    if (i > 1000) {
      const Scalar e1 = std::fabs(d.derivative(1) - Scalar(3) * std::cos(Scalar(3) * t));
      max_e1 = e1 > max_e1 ? e1 : max_e1;
    }
  }
  // |P_1(jw)| / |jw + 50|^3 * 27 with P_1(s) = s + 3*50: = |150 + 3j| 27 / |50 + 3j|^3
  const double expected = std::sqrt(150.0 * 150.0 + 9.0) * 27.0 / std::pow(2500.0 + 9.0, 1.5);
  expect(std::fabs(static_cast<double>(max_e1) - expected) < 0.02 * expected,
         "differentiator y' error (expected 3.2e-2)", static_cast<double>(max_e1), expected);
}

struct Dummy {
  using Scalar = float;
  static constexpr int n = 2, m = 1, p = 1;
  using State = Eigen::Matrix<float, 2, 1>;
  using Input = Eigen::Matrix<float, 1, 1>;
  using Output = Eigen::Matrix<float, 1, 1>;
  void reset(const State& x) noexcept { x_ = x; }
  obsynth::Status step(float, const Input&, const Output&) noexcept { return obsynth::Status::ok; }
  const State& estimate() const noexcept { return x_; }
  obsynth::Status status() const noexcept { return obsynth::Status::ok; }
  State x_;
};
static_assert(obsynth::is_observer_v<Dummy>);

}  // namespace

int main() {
  run<float>("float (FPv4-SP hardware)");
  run<double>("double (software floating point)");
  std::printf("RESULT %s (%d failures)\n", failures == 0 ? "PASS" : "FAIL", failures);
  return failures == 0 ? 0 : 1;
}
