// SPDX-License-Identifier: MIT
// Copyright (c) obsynth authors
//
// Compiled with the exact flags of the generated-code contract (see CMakeLists.txt:
// -Wall -Wextra -Werror -Wconversion -Wdouble-promotion -pedantic -fno-exceptions -fno-rtti,
// Eigen on a plain -I path so that obsynth/eigen.hpp's warning fence is exercised).
// Instantiates every runtime template for float and double; a warning anywhere (in particular
// a float -> double promotion in a float build) fails the build. The functions are called by
// test_strict.cpp so the code is also run.
#include "strict_instantiation.hpp"

#include <cmath>

#include "../../bench/handwritten_seed003.hpp"
#include "obsynth/differentiator.hpp"
#include "obsynth/eigen.hpp"
#include "obsynth/integrators.hpp"
#include "obsynth/newton.hpp"
#include "obsynth/numeric.hpp"
#include "obsynth/observer.hpp"
#include "obsynth/status.hpp"

template class obsynth::JetDifferentiator<float, 0>;
template class obsynth::JetDifferentiator<float, 1>;
template class obsynth::JetDifferentiator<float, 3>;
template class obsynth::JetDifferentiator<double, 2>;
template class obsynth::JetDifferentiator<double, 4>;
template class handwritten::seed003::CanonicalObserver<float>;
template class handwritten::seed003::CanonicalObserver<double>;

static_assert(obsynth::is_observer_v<handwritten::seed003::CanonicalObserver<float>>);
static_assert(obsynth::is_observer_v<handwritten::seed003::CanonicalObserver<double>>);
static_assert(obsynth::status_name(obsynth::Status::singular)[0] == 's');

namespace {

template <class Scalar>
StrictResult<Scalar> exercise() noexcept {
  using V2 = obsynth::Vector<Scalar, 2>;
  using M2 = obsynth::Matrix<Scalar, 2, 2>;
  StrictResult<Scalar> r;

  // Harmonic oscillator over one period with each integrator.
  auto osc = [](const V2& x, V2& dx) noexcept {
    dx(0) = x(1);
    dx(1) = -x(0);
  };
  const Scalar two_pi = Scalar(6.283185307179586);
  const int steps = 200;
  const Scalar dt = two_pi / Scalar(steps);
  V2 xe(Scalar(1), Scalar(0));
  V2 xh = xe;
  V2 xr = xe;
  for (int i = 0; i < steps; ++i) {
    obsynth::euler_step<Scalar, 2>(osc, dt, xe);
    obsynth::heun_step<Scalar, 2>(osc, dt, xh);
    obsynth::rk4_step<Scalar, 2>(osc, dt, xr);
  }
  r.euler_error = obsynth::inf_norm(xe - V2(Scalar(1), Scalar(0)));
  r.heun_error = obsynth::inf_norm(xh - V2(Scalar(1), Scalar(0)));
  r.rk4_error = obsynth::inf_norm(xr - V2(Scalar(1), Scalar(0)));

  // Newton on the seed 003 diffeomorphism, both variants.
  using Obs = handwritten::seed003::CanonicalObserver<Scalar>;
  const V2 x_true(Scalar(1.25f), Scalar(-0.5f));
  const V2 z = Obs::T(x_true);
  auto T = [](const V2& x, V2& tx) noexcept { tx = Obs::T(x); };
  auto tau = [](const V2& x, M2& t) noexcept { t << Scalar(0), Scalar(1), Scalar(-1), x(0); };
  auto jac = [](const V2& x, M2& j) noexcept { j << x(0), Scalar(-1), Scalar(1), Scalar(0); };
  V2 xa(Scalar(1), Scalar(0));
  const Scalar tol = sizeof(Scalar) == 4 ? Scalar(1e-6f) : Scalar(1e-13);
  const auto ra = obsynth::newton_solve_inverse_jacobian<Scalar, 2>(T, tau, z, xa, 20, tol);
  V2 xb(Scalar(1), Scalar(0));
  const auto rb = obsynth::newton_solve_jacobian<Scalar, 2>(T, jac, z, xb, 20, tol);
  r.newton_status = obsynth::worst(ra.status, rb.status);
  r.newton_error = obsynth::inf_norm(xa - x_true) + obsynth::inf_norm(xb - x_true);

  // Differentiator on a sinusoid.
  obsynth::JetDifferentiator<Scalar, 2> d(Scalar(0.02f));
  d.reset(Scalar(0));
  const Scalar ddt = Scalar(1e-3f);
  Scalar max_e1 = Scalar(0);
  for (int i = 1; i <= 2000; ++i) {
    const Scalar t = static_cast<Scalar>(i) * ddt;
    d.update(ddt, std::sin(t));
    if (i > 1000) {
      const Scalar e1 = std::abs(d.derivative(1) - std::cos(t));
      max_e1 = e1 > max_e1 ? e1 : max_e1;
    }
  }
  r.differentiator_error = max_e1;

  // Observer.
  Obs obs;
  obs.reset(V2(Scalar(0), Scalar(0)));
  typename Obs::Input u;
  u(0) = Scalar(0.5f);
  typename Obs::Output y;
  y(0) = Scalar(1);
  r.observer_status = obs.step(Scalar(1e-3f), u, y);
  return r;
}

}  // namespace

StrictResult<float> strict_exercise_float() noexcept { return exercise<float>(); }
StrictResult<double> strict_exercise_double() noexcept { return exercise<double>(); }
