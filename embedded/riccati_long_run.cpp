// SPDX-License-Identifier: MIT
// Copyright (c) obsynth authors
//
// The GENERATED Riccati observer generated/vanderpol_riccati.hpp (James-Baras, Q0 = N = R = I)
// in closed loop with the forced Van der Pol plant for OBSYNTH_RICCATI_STEPS (default 10^6)
// firmware steps of dt = 0.01, in float and in double (soft-float on the Cortex-M4F):
//  - every step returns Status::ok;
//  - after every step Q, read from the packed upper triangle of observer_state() (so symmetric
//    by construction), is finite and positive definite: the pivots of its L D L^T
//    (q11 > 0, q22 - q12^2 / q11 > 0) are checked here, independently of the runtime;
//  - the estimate is finite and, over the last 1000 steps, within OBSYNTH_RICCATI_TOL of the
//    plant (the zero-order-hold floor);
//  - no heap: Eigen is compiled with EIGEN_NO_MALLOC (asserts are on in this program), every
//    global operator new is counted, and on the target newlib's mallinfo() (bytes in use) is
//    unchanged across the run.
// The plant is integrated with RK4 at the same dt, with u = 0.5 sin(t) from an exact rotation
// recurrence (cheap in soft double), renormalised every step.
#define EIGEN_NO_MALLOC
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <new>

#if defined(__arm__)
#include <malloc.h>
#endif

#include "vanderpol_riccati.hpp"

#ifndef OBSYNTH_RICCATI_STEPS
#define OBSYNTH_RICCATI_STEPS 1000000L
#endif
#ifndef OBSYNTH_RICCATI_TOL
#define OBSYNTH_RICCATI_TOL 8e-2
#endif

namespace {
unsigned long g_news = 0;
}

void* operator new(std::size_t size) {
  ++g_news;
  void* p = std::malloc(size ? size : 1);
  if (!p) std::abort();
  return p;
}
void operator delete(void* p) noexcept {
  std::free(p);
}
void operator delete(void* p, std::size_t) noexcept {
  std::free(p);
}

namespace {

template <class S>
struct Result {
  long not_ok = 0, not_pd = 0, not_finite = 0;
  double min_pivot = 1e300, max_q = 0, final_err = 0;
};

template <class S>
Result<S> run(long steps) {
  using Obs = obsynth_gen::vanderpol::VanderpolRiccati<S>;
  using F = obsynth_gen::vanderpol::RiccatiFunctions<S>;
  using State = typename Obs::State;
  Result<S> r;
  Obs obs;
  State x, xh0, k1, k2, k3, k4, a, gx;
  x << S(1), S(0);
  xh0 << S(-1), S(1);
  obs.reset(xh0);
  const S dt = S(0.01);
  // (c, s) = (cos t, sin t), rotated by dt each step.
  double c = 1, s = 0;
  const double cd = std::cos(0.01), sd = std::sin(0.01);
  auto field = [&](const State& xs, S uu, State& out) {
    typename Obs::Input u;
    u(0) = uu;
    F::f(xs, out);
    F::g(xs, u, gx);
    out += gx;
  };
  for (long k = 0; k < steps; ++k) {
    const S u0 = static_cast<S>(0.5 * s);
    const double c1 = c * cd - s * sd, s1 = s * cd + c * sd;
    const double nrm = 1.0 / std::sqrt(c1 * c1 + s1 * s1);
    // midpoint input for the plant's RK4 (sin(t + dt/2) from the half-angle rotation)
    const S uh = static_cast<S>(0.5 * (s * std::cos(0.005) + c * std::sin(0.005)));
    const S u1 = static_cast<S>(0.5 * s1 * nrm);
    typename Obs::Input u;
    u(0) = u0;
    typename Obs::Output y;
    F::h(x, y);
    r.not_ok += obs.step(dt, u, y) != obsynth::Status::ok;
    const auto& w = obs.observer_state();  // (m1, m2, q11, q12, q22)
    const double q11 = static_cast<double>(w(2)), q12 = static_cast<double>(w(3)),
                 q22 = static_cast<double>(w(4));
    const double piv2 = q22 - q12 * q12 / q11;
    if (!std::isfinite(q11) || !std::isfinite(q12) || !std::isfinite(q22) ||
        !std::isfinite(static_cast<double>(w(0))) || !std::isfinite(static_cast<double>(w(1))))
      ++r.not_finite;
    if (!(q11 > 0) || !(piv2 > 0)) ++r.not_pd;
    if (q11 < r.min_pivot) r.min_pivot = q11;
    if (piv2 < r.min_pivot) r.min_pivot = piv2;
    r.max_q =
        std::fmax(r.max_q, std::fmax(std::fabs(q11), std::fmax(std::fabs(q12), std::fabs(q22))));
    field(x, u0, k1);
    a = x + (dt / S(2)) * k1;
    field(a, uh, k2);
    a = x + (dt / S(2)) * k2;
    field(a, uh, k3);
    a = x + dt * k3;
    field(a, u1, k4);
    x += (dt / S(6)) * (k1 + S(2) * k2 + S(2) * k3 + k4);
    c = c1 * nrm;
    s = s1 * nrm;
    if (k >= steps - 1000)
      for (int i = 0; i < 2; ++i)
        r.final_err =
            std::fmax(r.final_err, std::fabs(static_cast<double>(x(i) - obs.estimate()(i))));
  }
  return r;
}

template <class S>
bool report(const char* name, const Result<S>& r, long steps) {
  std::printf(
      "%s: %ld steps: not ok %ld, Q not positive definite %ld, not finite %ld; min L D L^T pivot "
      "of Q %.4g, max |Q_ij| %.4g; max |x - xh| over the last 1000 steps %.3g (tolerance %.3g)\n",
      name, steps, r.not_ok, r.not_pd, r.not_finite, r.min_pivot, r.max_q, r.final_err,
      OBSYNTH_RICCATI_TOL);
  return r.not_ok == 0 && r.not_pd == 0 && r.not_finite == 0 && r.final_err < OBSYNTH_RICCATI_TOL;
}

}  // namespace

int main() {
  const long steps = OBSYNTH_RICCATI_STEPS;
  std::printf("riccati long run (generated vanderpol_riccati.hpp)\n");  // warms up printf
#if defined(__arm__)
  const int heap_before = mallinfo().uordblks;
#endif
  const unsigned long news_before = g_news;
  const Result<float> rf = run<float>(steps);
  const Result<double> rd = run<double>(steps);
  const unsigned long news = g_news - news_before;
#if defined(__arm__)
  const int heap_after = mallinfo().uordblks;
#endif
  bool ok = report("float", rf, steps);
  ok = report("double", rd, steps) && ok;
  std::printf("operator new calls during the runs: %lu\n", news);
  ok = ok && news == 0;
#if defined(__arm__)
  std::printf("heap bytes in use (mallinfo): before %d, after %d\n", heap_before, heap_after);
  ok = ok && heap_before == heap_after;
#endif
  std::printf("%s\n", ok ? "PASS" : "FAIL");
  return ok ? 0 : 1;
}
