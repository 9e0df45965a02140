// SPDX-License-Identifier: MIT
// Copyright (c) obsynth authors
//
// Closed-loop check of the hand-written seed 003 canonical observer
// (bench/handwritten_seed003.hpp), built unchanged for the host and for a Cortex-M4F
// (embedded/run-qemu.sh). Single precision by default (-DOBSYNTH_SCALAR=double for a host
// reference run).
//
// Plant  x' = [-x2 + (1+x1) u, -x1 x2 + u],  y = x1,  x(0) = (0.5, -0.3),
//        u(t) = sin(t) applied through a zero-order hold (as a digital controller would),
//        integrated with one RK4 step per sample.
// Observer poles -2, -3 (s^2 + 5 s + 6), zh(0) = 0, i.e. xh(0) = T^-1(0) = (0, 0).
// dt = 1e-3, 5 s; a line every 0.5 s:  traj t x1 x2 xh1 xh2 dev
//
// Checks (exit status 1 if any fails):
// 1. In z = T(x) coordinates the error is exactly linear, e' = (A - K C) e, so it must follow
//    e(t) = exp((A - K C) t) e(0) (modes e^{-2t}, e^{-3t}, evaluated in closed form below).
//    The observer holds y constant over each step while the true y moves, which adds an O(dt)
//    deviation (about 30 dt on this trajectory, where y reaches ~9.6 and |y'| ~5.7; it scales
//    linearly with dt). Required: |e(t) - e_pred(t)|_inf <= 50 dt at every sample.
// 2. At t = 5 s: |x - xh|_inf <= 5e-3 (the pole-predicted part is e^{-10} |e(0)| ~ 1e-4; the
//    rest is the O(dt) sampling floor).
// 3. Every observer step returns Status::ok and all values stay finite.
//
// -DOBSYNTH_SEED003_PORTABLE_SIN=1 evaluates u = sin(t) in double and rounds it to Scalar, so
// that the input sequence does not depend on the C library's sinf (newlib and glibc differ in
// the last bit for some arguments); with -ffp-contract=off on both sides the host and
// Cortex-M4F runs then print identical trajectories (embedded/CMakeLists.txt).
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>

#include "../bench/handwritten_seed003.hpp"
#include "obsynth/integrators.hpp"
#include "obsynth/observer.hpp"
#include "stack_probe.hpp"

#ifndef OBSYNTH_SCALAR
#define OBSYNTH_SCALAR float
#endif
#ifndef OBSYNTH_SEED003_PORTABLE_SIN
#define OBSYNTH_SEED003_PORTABLE_SIN 0
#endif

namespace {

using Scalar = OBSYNTH_SCALAR;
using Observer = handwritten::seed003::CanonicalObserver<Scalar>;
using State = Observer::State;
using Z = Observer::Z;

static_assert(obsynth::is_observer_v<Observer>, "seed 003 observer must meet the interface");

}  // namespace

// Not inlined, so that -fstack-usage and the stack probe see the observer step on its own.
__attribute__((noinline)) obsynth::Status seed003_observer_step(Observer& obs, Scalar dt,
                                                                const Observer::Input& u,
                                                                const Observer::Output& y) noexcept {
  return obs.step(dt, u, y);
}

__attribute__((noinline)) void seed003_plant_step(State& x, Scalar dt, Scalar u) noexcept {
  obsynth::rk4_step<Scalar, 2>(
      [u](const State& xs, State& dx) noexcept { dx = Observer::plant(xs, u); }, dt, x);
}

namespace {

// exp(Acl t) e0 for Acl = [[0, -c0], [1, -c1]] with distinct real eigenvalues l1, l2:
// exp(Acl t) = (e^{l1 t} (Acl - l2 I) - e^{l2 t} (Acl - l1 I)) / (l1 - l2).
Z predicted_error(Scalar c0, Scalar c1, Scalar l1, Scalar l2, Scalar t, const Z& e0) noexcept {
  const Scalar E1 = std::exp(l1 * t);
  const Scalar E2 = std::exp(l2 * t);
  const Scalar d = l1 - l2;
  const Scalar m11 = (E1 * (-l2) - E2 * (-l1)) / d;
  const Scalar m12 = (E1 - E2) * (-c0) / d;
  const Scalar m21 = (E1 - E2) / d;
  const Scalar m22 = (E1 * (-c1 - l2) - E2 * (-c1 - l1)) / d;
  return Z(m11 * e0(0) + m12 * e0(1), m21 * e0(0) + m22 * e0(1));
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

// FNV-1a over the bit patterns of a state, so that two runs can be compared bit for bit at
// every step, not only at the printed samples.
std::uint32_t hash_state(std::uint32_t h, const State& v) noexcept {
  for (int i = 0; i < 2; ++i) {
    unsigned char bytes[sizeof(Scalar)];
    const Scalar s = v(i);
    std::memcpy(bytes, &s, sizeof s);
    for (unsigned char b : bytes) h = (h ^ b) * 16777619u;
  }
  return h;
}

}  // namespace

int main() {
  const Scalar pole1 = lit(-2);
  const Scalar pole2 = lit(-3);
  const Scalar dt = lit(1e-3);
  const int steps = 5000;
  const int print_every = 500;
  const Scalar dev_bound = lit(50) * dt;
  const Scalar final_bound = lit(5e-3);

  Observer obs(pole1, pole2);
  obs.reset_z(Z::Zero());
  State x(lit(0.5), lit(-0.3));
  const Z e0 = obs.z_estimate() - Observer::T(x);

  std::printf("# seed003 canonical observer, poles %g %g, dt %g, scalar %s\n", d(pole1), d(pole2),
              d(dt), sizeof(Scalar) == 4 ? "float" : "double");
  std::printf("#    t             x1            x2            xh1           xh2           dev\n");

  bool ok = true;
  std::uint32_t hash = 2166136261u;
  Scalar max_dev = Scalar(0);
  std::size_t observer_stack = 0;
  std::size_t plant_stack = 0;
  for (int k = 0;; ++k) {
    const Scalar t = static_cast<Scalar>(k) * dt;
    const Z ez = obs.z_estimate() - Observer::T(x);
    const Z ep = predicted_error(obs.c0(), obs.c1(), pole1, pole2, t, e0);
    const Scalar dev = obsynth::inf_norm(ez - ep);
    if (!(dev <= dev_bound)) {
      if (ok) std::printf("FAIL: t=%.3f |e - e_pred| = %.3e > %.3e\n", d(t), d(dev), d(dev_bound));
      ok = false;
    }
    max_dev = dev > max_dev ? dev : max_dev;
    hash = hash_state(hash_state(hash, x), obs.estimate());
    if (k % print_every == 0) {
      const State& xh = obs.estimate();
      std::printf("traj %.6e %.6e %.6e %.6e %.6e %.6e\n", d(t), d(x(0)), d(x(1)), d(xh(0)),
                  d(xh(1)), d(dev));
    }
    if (k == steps) break;

#if OBSYNTH_SEED003_PORTABLE_SIN
    // sin in double, rounded once: identical on glibc and newlib (used by the bit-exact test)
    const Scalar uk = static_cast<Scalar>(std::sin(static_cast<double>(t)));
#else
    const Scalar uk = std::sin(t);
#endif
    Observer::Input u;
    u(0) = uk;
    Observer::Output y;
    y(0) = x(0);
    obsynth::Status s;
    if (k == 0) {
      auto probe = obsynth_embedded::stack_paint(4096);
      s = seed003_observer_step(obs, dt, u, y);
      observer_stack = obsynth_embedded::stack_high_water(probe);
      probe = obsynth_embedded::stack_paint(4096);
      seed003_plant_step(x, dt, uk);
      plant_stack = obsynth_embedded::stack_high_water(probe);
    } else {
      s = seed003_observer_step(obs, dt, u, y);
      seed003_plant_step(x, dt, uk);
    }
    if (s != obsynth::Status::ok || !obsynth::all_finite(x)) {
      std::printf("FAIL: t=%.3f status %s\n", d(t), obsynth::status_name(s));
      ok = false;
      break;
    }
  }

  const Scalar final_err = obsynth::inf_norm(obs.estimate() - x);
  if (!(final_err <= final_bound)) {
    std::printf("FAIL: final |x - xh|_inf = %.3e > %.3e\n", d(final_err), d(final_bound));
    ok = false;
  }
  std::printf("max |e - e_pred|_inf = %.3e (bound %.3e), final |x - xh|_inf = %.3e (bound %.3e)\n",
              d(max_dev), d(dev_bound), d(final_err), d(final_bound));
  std::printf("hash %08lx (FNV-1a of x and xh at every step)\n", static_cast<unsigned long>(hash));
  if (obsynth_embedded::kStackProbeAvailable) {
    std::printf("stack (painted): observer step %u bytes, plant step %u bytes\n",
                static_cast<unsigned>(observer_stack), static_cast<unsigned>(plant_stack));
  }
  std::printf("RESULT %s\n", ok ? "PASS" : "FAIL");
  return ok ? 0 : 1;
}
