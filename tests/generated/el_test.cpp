// Tests of a generated extended-linearization observer header (C++) under the contract flags,
// in double and float: numeric equivalence of x_rhs and injection with the hand-derived
// reference (el_reference.hpp), closed loop with the firmware step (u, y held over dt) near the
// equilibrium family, zero heap allocations while stepping.
// Built per model with OBSYNTH_EL_HEADER, OBSYNTH_NS, OBSYNTH_CLASS, OBSYNTH_EL_MODEL.
#include <cmath>
#include <cstdio>

#include OBSYNTH_EL_HEADER
#include "alloc_counter.hpp"
#include "el_reference.hpp"

namespace gen = obsynth_gen::OBSYNTH_NS;

namespace {

int passed = 0, failed = 0;

void expect(bool ok, const char* what, double got = 0, double want = 0) {
  if (ok) {
    ++passed;
  } else {
    ++failed;
    std::printf("FAIL: %s (got %.17g, want %.17g)\n", what, got, want);
  }
}

template <class Scalar>
void numeric_equivalence() {
  using F = gen::ExtendedLinearizationFunctions<Scalar>;
  const double tol = sizeof(Scalar) == sizeof(double) ? 1e-13 : 2e-6;
  for (int a = 0; a < 7; ++a)
    for (int b = 0; b < 5; ++b) {
      const double x1 = -0.9 + 0.3 * a, x2 = -1 + 0.5 * b, uu = 0.1 * a - 0.2 * b,
                   yy = 0.13 * b - 0.4;
      typename F::State xh, out, kout;
      typename F::Input u;
      typename F::Output y;
      xh << static_cast<Scalar>(x1), static_cast<Scalar>(x2);
      u << static_cast<Scalar>(uu);
      y << static_cast<Scalar>(yy);
      F::x_rhs(xh, u, y, out);
      F::injection(y, kout);
      const long double xl[2] = {static_cast<long double>(static_cast<Scalar>(x1)),
                                 static_cast<long double>(static_cast<Scalar>(x2))};
      long double want[2], kw[2];
      el_ref::rhs(xl, static_cast<Scalar>(uu), static_cast<Scalar>(yy), want);
      el_ref::k(static_cast<Scalar>(yy), kw);
      for (int i = 0; i < 2; ++i) {
        const double scale = 1 + std::fabs(static_cast<double>(want[i]));
        expect(std::fabs(static_cast<double>(out(i)) - static_cast<double>(want[i])) <=
                   tol * scale * 4,
               "x_rhs", static_cast<double>(out(i)), static_cast<double>(want[i]));
        expect(std::fabs(static_cast<double>(kout(i)) - static_cast<double>(kw[i])) <=
                   tol * (1 + std::fabs(static_cast<double>(kw[i]))),
               "injection", static_cast<double>(kout(i)), static_cast<double>(kw[i]));
      }
    }
}

template <class Scalar>
void closed_loop() {
  using Obs = gen::OBSYNTH_CLASS<Scalar>;
  Obs o;
  typename Obs::State xh0;
  xh0 << static_cast<Scalar>(el_ref::xh0[0]), static_cast<Scalar>(el_ref::xh0[1]);
  o.reset(xh0);
  long double x[2] = {el_ref::x0[0], el_ref::x0[1]};
  const double dt = 1e-3;
  const long steps = static_cast<long>(el_ref::t_end / dt + 0.5);
  long not_ok = 0;
  obsynth::test::AllocationCounter counter;
  for (long k = 0; k < steps; ++k) {
    const double t = static_cast<double>(k) * dt;
    typename Obs::Input u;
    typename Obs::Output y;
    u << static_cast<Scalar>(el_ref::u_of_t(t));
    y << static_cast<Scalar>(el_ref::h(x));
    not_ok += o.step(static_cast<Scalar>(dt), u, y) != obsynth::Status::ok;
    // The plant: RK4 in long double with the exact input.
    long double k1[2], k2[2], k3[2], k4[2], a[2];
    el_ref::field(x, el_ref::u_of_t(t), k1);
    for (int i = 0; i < 2; ++i) a[i] = x[i] + dt / 2 * k1[i];
    el_ref::field(a, el_ref::u_of_t(t + dt / 2), k2);
    for (int i = 0; i < 2; ++i) a[i] = x[i] + dt / 2 * k2[i];
    el_ref::field(a, el_ref::u_of_t(t + dt / 2), k3);
    for (int i = 0; i < 2; ++i) a[i] = x[i] + dt * k3[i];
    el_ref::field(a, el_ref::u_of_t(t + dt), k4);
    for (int i = 0; i < 2; ++i) x[i] += dt / 6 * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i]);
  }
  const std::size_t allocations = counter.allocations();
  expect(allocations == 0, "no heap allocation while stepping", static_cast<double>(allocations));
  expect(not_ok == 0, "every step returns ok", static_cast<double>(not_ok));
  double err = 0;
  for (int i = 0; i < 2; ++i)
    err =
        std::fmax(err, std::fabs(static_cast<double>(x[i]) - static_cast<double>(o.estimate()(i))));
  // u, y held over dt: the floor is first order in dt times |y'| (small near the family).
  const double tol = sizeof(Scalar) == sizeof(double) ? 1e-3 : 2e-3;
  expect(err < tol, "closed loop error", err, tol);
  std::printf("closed loop (%s): |x - xh|_inf = %.3g (initial %.3g)\n",
              sizeof(Scalar) == sizeof(double) ? "double" : "float", err,
              std::fabs(el_ref::xh0[0] - el_ref::x0[0]));
}

}  // namespace

int main() {
  numeric_equivalence<double>();
  numeric_equivalence<float>();
  closed_loop<double>();
  closed_loop<float>();
  std::printf("%d passed, %d failed\n", passed, failed);
  return failed == 0 ? 0 : 1;
}
