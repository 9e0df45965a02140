// SPDX-License-Identifier: MIT
// Copyright (c) obsynth authors
//
// Closed-loop check of the GENERATED canonical observer for slawinski17
// (generated/slawinski17_canonical.hpp, class obsynth_gen::slawinski17::Slawinski17Canonical),
// built unchanged for the host (CMake target generated_closed_loop_host) and for a Cortex-M4F
// (embedded/run-qemu.sh, -I generated). Single precision by default (-DOBSYNTH_SCALAR=double
// for a host reference run).
//
// Plant  x' = f(x) + g(x, u) = [-x2 + (1+x1) u, -x1 x2 + u],  y = h(x) = x1,
//        x(0) = (0.5, -0.3); f, g, h are the generated CanonicalFunctions<Scalar>.
//        u(t) = sin(t) through a zero-order hold (as a digital controller would), the plant
//        integrated with one RK4 step per sample.
// Observer: Slawinski17Canonical<Scalar>, reset(xh0 = (0, 0)), error poles -137/50, -343/100
// (the default from the model's time scale, fixed at generation time and stated in the header's
// banner: s^2 + 6.17 s + 9.3982). dt = 1e-3, 5 s; a line every 0.5 s:
//   traj t x1 x2 xh1 xh2 dev |e_z| |e_pred|
//
// Checks (exit status 1 if any fails):
// 0. The closed-loop error matrix of the generated code, read off its z-realisation right-hand
//    side (Acl e_j = z_rhs(e_j, c = 0)), is the companion matrix [[0, -c0], [1, -c1]] of
//    (s + 2.74)(s + 3.43) = s^2 + 6.17 s + 9.3982, literal for literal (K as the banner prints
//    it), and
//    step_constant(u, y) - l(u, y) = K y with K = (c0, c1) (the output injection).
// 1. In z = T(x) coordinates the error is exactly linear, e' = Acl e, so e(t) = zh(t) - T(x(t))
//    must follow e_pred(t) = exp(Acl t) e(0) (modes e^{-2.74t} and e^{-3.43t}, closed form below).
//    The observer holds y constant over each step while the true y moves; that adds an O(dt)
//    deviation: observed 29.8 dt (float; 29.7 dt in double, the same at dt = 2e-3, 5e-4 and
//    2.5e-4, so it is the sampling floor and not rounding), largest near t = 2.75 s where y
//    is large (8 to 9.6) and still rising. Required: |e - e_pred|_inf <= 50 dt at every one of
//    the 5001 samples.
// 2. At t = 5 s: |x - xh|_inf <= 5e-3 (the pole-predicted part of the z error is
//    |e_pred(5)| = 1.2e-4, the e^{-2t} mode: e^{-10} = 4.5e-5 times its coefficient; the rest
//    is the O(dt) floor; observed 2.0e-3).
// 3. Every observer step returns Status::ok, status() agrees, and all values stay finite.
//
// -DOBSYNTH_GENERATED_PORTABLE_SIN=1 evaluates u = sin(t) in double and rounds it to Scalar, so
// that the input sequence does not depend on the C library's sinf (newlib and glibc differ in
// the last bit for some arguments); with -ffp-contract=off on both sides the host and
// Cortex-M4F runs then print identical trajectories (embedded/CMakeLists.txt).
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>

#include "obsynth/integrators.hpp"
#include "obsynth/numeric.hpp"
#include "obsynth/observer.hpp"
#include "obsynth/status.hpp"
#include "slawinski17_canonical.hpp"
#include "stack_probe.hpp"

#ifndef OBSYNTH_SCALAR
#define OBSYNTH_SCALAR float
#endif
#ifndef OBSYNTH_GENERATED_PORTABLE_SIN
#define OBSYNTH_GENERATED_PORTABLE_SIN 0
#endif

namespace {

using Scalar = OBSYNTH_SCALAR;
using Observer = obsynth_gen::slawinski17::Slawinski17Canonical<Scalar>;
using F = obsynth_gen::slawinski17::CanonicalFunctions<Scalar>;
using State = Observer::State;
using Input = Observer::Input;
using Output = Observer::Output;

static_assert(obsynth::is_observer_v<Observer>, "generated observer must meet the interface");
static_assert(Observer::n == 2 && Observer::m == 1 && Observer::p == 1, "slawinski17 is 2/1/1");

}  // namespace

// Not inlined, so that -fstack-usage, the symbol sizes and the stack probe see the generated
// observer's step on its own (Slawinski17Canonical<float>::step is inlined into it).
__attribute__((noinline)) obsynth::Status generated_observer_step(Observer& obs, Scalar dt,
                                                                  const Input& u,
                                                                  const Output& y) noexcept {
  return obs.step(dt, u, y);
}

// Plant x' = f(x) + g(x, u) with the generated model maps, u held over the step.
__attribute__((noinline)) void generated_plant_step(State& x, Scalar dt, Scalar uk) noexcept {
  Input u;
  u(0) = uk;
  obsynth::rk4_step<Scalar, 2>(
      [&u](const State& xs, State& dx) noexcept {
        State fx;
        State gx;
        F::f(xs, fx);
        F::g(xs, u, gx);
        dx = fx + gx;
      },
      dt, x);
}

namespace {

// exp(Acl t) e0 for Acl = [[0, -c0], [1, -c1]] with distinct real eigenvalues l1, l2:
// exp(Acl t) = (e^{l1 t} (Acl - l2 I) - e^{l2 t} (Acl - l1 I)) / (l1 - l2).
State predicted_error(Scalar c0, Scalar c1, Scalar l1, Scalar l2, Scalar t,
                      const State& e0) noexcept {
  const Scalar E1 = std::exp(l1 * t);
  const Scalar E2 = std::exp(l2 * t);
  const Scalar dl = l1 - l2;
  const Scalar m11 = (E1 * (-l2) - E2 * (-l1)) / dl;
  const Scalar m12 = (E1 - E2) * (-c0) / dl;
  const Scalar m21 = (E1 - E2) / dl;
  const Scalar m22 = (E1 * (-c1 - l2) - E2 * (-c1 - l1)) / dl;
  return State(m11 * e0(0) + m12 * e0(1), m21 * e0(0) + m22 * e0(1));
}

// For printf (float varargs would be promoted implicitly; -Wdouble-promotion wants it explicit).
template <class T>
double d(T v) noexcept {
  return static_cast<double>(v);
}

// A literal in the working precision (a template, so that no -Wuseless-cast fires whichever
// type OBSYNTH_SCALAR is).
template <class T = Scalar>
constexpr T lit(double v) noexcept {
  return static_cast<T>(v);
}

State T_of(const State& x) noexcept {
  State z;
  F::T(x, z);
  return z;
}

// FNV-1a over the bit patterns of a vector, so that two runs can be compared bit for bit at
// every step, not only at the printed samples.
std::uint32_t hash_vec(std::uint32_t h, const State& v) noexcept {
  for (int i = 0; i < 2; ++i) {
    unsigned char bytes[sizeof(Scalar)];
    const Scalar s = v(i);
    std::memcpy(bytes, &s, sizeof s);
    for (unsigned char b : bytes) h = (h ^ b) * 16777619u;
  }
  return h;
}

// Check 0: the generated z-realisation is the designed linear error system.
bool check_structure(Scalar c0, Scalar c1) noexcept {
  bool ok = true;
  const State zero = State::Zero();
  State col0;
  State col1;
  F::z_rhs(State(lit(1), lit(0)), zero, col0);
  F::z_rhs(State(lit(0), lit(1)), zero, col1);
  const bool companion = col0(0) == lit(0) && col0(1) == lit(1) && col1(0) == -c0 && col1(1) == -c1;
  std::printf("generated Acl = [[%g, %g], [%g, %g]] (expected [[0, %g], [1, %g]]) %s\n", d(col0(0)),
              d(col1(0)), d(col0(1)), d(col1(1)), d(-c0), d(-c1), companion ? "ok" : "FAIL");
  ok = ok && companion;
  // step_constant(u, y) - l(u, y) = K y at a few (u, y); exact up to rounding of the sums.
  const Scalar samples[3][2] = {{lit(0.25), lit(-1.5)}, {lit(-0.75), lit(2)}, {lit(1), lit(0.5)}};
  for (const auto& s : samples) {
    Input u;
    u(0) = s[0];
    Output y;
    y(0) = s[1];
    State c;
    State l;
    F::step_constant(u, y, c);
    F::l(u, y, l);
    const State k_y = c - l;
    const Scalar tol = lit(1e-5) * (lit(1) + obsynth::inf_norm(c));
    if (!(std::abs(k_y(0) - c0 * s[1]) <= tol && std::abs(k_y(1) - c1 * s[1]) <= tol)) {
      std::printf("FAIL: step_constant - l = (%g, %g) != K y = (%g, %g) at u=%g y=%g\n", d(k_y(0)),
                  d(k_y(1)), d(c0 * s[1]), d(c1 * s[1]), d(s[0]), d(s[1]));
      ok = false;
    }
  }
  return ok;
}

}  // namespace

int main() {
  // Design: poles -137/50, -343/100 (generated/slawinski17_canonical.hpp banner)
  const Scalar pole1 = lit(-2.74);
  const Scalar pole2 = lit(-3.43);
  const Scalar c0 = lit(9.3982);  // pole1 pole2, K as the banner prints it (46991/5000)
  const Scalar c1 = lit(6.17);    // -(pole1 + pole2) (617/100)
  const Scalar dt = lit(1e-3);
  const int steps = 5000;
  const int print_every = 500;
  const Scalar dev_bound = lit(50) * dt;
  const Scalar final_bound = lit(5e-3);

  std::printf("# generated slawinski17 canonical observer, poles %g %g, dt %g, scalar %s\n",
              d(pole1), d(pole2), d(dt), sizeof(Scalar) == 4 ? "float" : "double");
  bool ok = check_structure(c0, c1);

  Observer obs;
  obs.reset(State::Zero());
  State x(lit(0.5), lit(-0.3));
  const State e0 = obs.observer_state() - T_of(x);
  if (obs.status() != obsynth::Status::ok) {
    std::printf("FAIL: status after reset: %s\n", obsynth::status_name(obs.status()));
    ok = false;
  }

  std::printf(
      "#    t             x1            x2            xh1           xh2           dev"
      "           |e_z|         |e_pred|\n");
  std::uint32_t hash = 2166136261u;
  Scalar max_dev = Scalar(0);
  Scalar max_dev_t = Scalar(0);
  std::size_t observer_stack = 0;
  std::size_t plant_stack = 0;
  for (int k = 0;; ++k) {
    const Scalar t = static_cast<Scalar>(k) * dt;
    const State ez = obs.observer_state() - T_of(x);
    const State ep = predicted_error(c0, c1, pole1, pole2, t, e0);
    const Scalar dev = obsynth::inf_norm(ez - ep);
    if (!(dev <= dev_bound)) {
      if (ok) std::printf("FAIL: t=%.3f |e - e_pred| = %.3e > %.3e\n", d(t), d(dev), d(dev_bound));
      ok = false;
    }
    if (dev > max_dev) {
      max_dev = dev;
      max_dev_t = t;
    }
    hash = hash_vec(hash_vec(hash_vec(hash, x), obs.observer_state()), obs.estimate());
    if (k % print_every == 0) {
      const State& xh = obs.estimate();
      std::printf("traj %.6e %.6e %.6e %.6e %.6e %.6e %.6e %.6e\n", d(t), d(x(0)), d(x(1)),
                  d(xh(0)), d(xh(1)), d(dev), d(obsynth::inf_norm(ez)), d(obsynth::inf_norm(ep)));
    }
    if (k == steps) break;

#if OBSYNTH_GENERATED_PORTABLE_SIN
    // sin in double, rounded once: identical on glibc and newlib (used by the bit-exact test)
    const Scalar uk = static_cast<Scalar>(std::sin(static_cast<double>(t)));
#else
    const Scalar uk = std::sin(t);
#endif
    Input u;
    u(0) = uk;
    Output y;
    F::h(x, y);  // y = x1, sampled at t
    obsynth::Status s;
    if (k == 0) {
      auto probe = obsynth_embedded::stack_paint(4096);
      s = generated_observer_step(obs, dt, u, y);
      observer_stack = obsynth_embedded::stack_high_water(probe);
      probe = obsynth_embedded::stack_paint(4096);
      generated_plant_step(x, dt, uk);
      plant_stack = obsynth_embedded::stack_high_water(probe);
    } else {
      s = generated_observer_step(obs, dt, u, y);
      generated_plant_step(x, dt, uk);
    }
    if (s != obsynth::Status::ok || obs.status() != s || !obsynth::all_finite(x) ||
        !obsynth::all_finite(obs.estimate())) {
      std::printf("FAIL: t=%.3f status %s\n", d(t), obsynth::status_name(s));
      ok = false;
      break;
    }
  }

  const State e_end = obs.observer_state() - T_of(x);
  const Scalar final_err = obsynth::inf_norm(obs.estimate() - x);
  if (!(final_err <= final_bound)) {
    std::printf("FAIL: final |x - xh|_inf = %.3e > %.3e\n", d(final_err), d(final_bound));
    ok = false;
  }
  std::printf("|e_z(0)|_inf = %.3e, |e_z(5)|_inf = %.3e, |e_pred(5)|_inf = %.3e\n",
              d(obsynth::inf_norm(e0)), d(obsynth::inf_norm(e_end)),
              d(obsynth::inf_norm(
                  predicted_error(c0, c1, pole1, pole2, static_cast<Scalar>(steps) * dt, e0))));
  std::printf(
      "max |e - e_pred|_inf = %.3e = %.1f dt at t=%.3f (bound %.3e), "
      "final |x - xh|_inf = %.3e (bound %.3e)\n",
      d(max_dev), d(max_dev / dt), d(max_dev_t), d(dev_bound), d(final_err), d(final_bound));
  std::printf("hash %08lx (FNV-1a of x, zh and xh at every step)\n",
              static_cast<unsigned long>(hash));
  if (obsynth_embedded::kStackProbeAvailable) {
    std::printf("stack (painted): observer step %u bytes, plant step %u bytes\n",
                static_cast<unsigned>(observer_stack), static_cast<unsigned>(plant_stack));
  }
  std::printf("RESULT %s\n", ok ? "PASS" : "FAIL");
  return ok ? 0 : 1;
}
