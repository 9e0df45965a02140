// Tests of a generated C99 extended-linearization observer pair (--language c), compiled as C
// under the strict flags and driven from C++ in the pair's scalar type: numeric equivalence of
// x_rhs and injection with the hand-derived reference (el_reference.hpp) and the firmware step
// in closed loop near the equilibrium family.
#include <cmath>
#include <cstdio>

#include OBSYNTH_C_HEADER
#include "el_reference.hpp"

#define OBSYNTH_CAT2(a, b) a##_##b
#define OBSYNTH_CAT(a, b) OBSYNTH_CAT2(a, b)
#define C_(name) OBSYNTH_CAT(OBSYNTH_C_PREFIX, name)

using Scalar = C_(scalar);

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

void numeric_equivalence() {
  const double tol = sizeof(Scalar) == sizeof(double) ? 1e-13 : 2e-6;
  for (int a = 0; a < 7; ++a)
    for (int b = 0; b < 5; ++b) {
      const Scalar xh[2] = {static_cast<Scalar>(-0.9 + 0.3 * a), static_cast<Scalar>(-1 + 0.5 * b)};
      const Scalar u[1] = {static_cast<Scalar>(0.1 * a - 0.2 * b)};
      const Scalar y[1] = {static_cast<Scalar>(0.13 * b - 0.4)};
      Scalar out[2], kout[2];
      C_(x_rhs)(xh, u, y, out);
      C_(injection)(y, kout);
      const long double xl[2] = {xh[0], xh[1]};
      long double want[2], kw[2];
      el_ref::rhs(xl, u[0], y[0], want);
      el_ref::k(y[0], kw);
      for (int i = 0; i < 2; ++i) {
        expect(std::fabs(static_cast<double>(out[i]) - static_cast<double>(want[i])) <=
                   4 * tol * (1 + std::fabs(static_cast<double>(want[i]))),
               "x_rhs", static_cast<double>(out[i]), static_cast<double>(want[i]));
        expect(std::fabs(static_cast<double>(kout[i]) - static_cast<double>(kw[i])) <=
                   tol * (1 + std::fabs(static_cast<double>(kw[i]))),
               "injection", static_cast<double>(kout[i]), static_cast<double>(kw[i]));
      }
    }
}

void closed_loop() {
  C_(observer) o;
  C_(init)(&o);
  const Scalar xh0[2] = {static_cast<Scalar>(el_ref::xh0[0]), static_cast<Scalar>(el_ref::xh0[1])};
  C_(reset)(&o, xh0);
  long double x[2] = {el_ref::x0[0], el_ref::x0[1]};
  const double dt = 1e-3;
  const long steps = static_cast<long>(el_ref::t_end / dt + 0.5);
  long not_ok = 0;
  for (long k = 0; k < steps; ++k) {
    const double t = static_cast<double>(k) * dt;
    const Scalar u[1] = {static_cast<Scalar>(el_ref::u_of_t(t))};
    const Scalar y[1] = {static_cast<Scalar>(el_ref::h(x))};
    not_ok += C_(step)(&o, static_cast<Scalar>(dt), u, y) != C_(ok);
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
  expect(not_ok == 0, "every step returns ok", static_cast<double>(not_ok));
  double err = 0;
  for (int i = 0; i < 2; ++i)
    err = std::fmax(err, std::fabs(static_cast<double>(x[i]) - static_cast<double>(o.xh[i])));
  const double tol = sizeof(Scalar) == sizeof(double) ? 1e-3 : 2e-3;
  expect(err < tol, "closed loop error", err, tol);
  std::printf("closed loop (C): |x - xh|_inf = %.3g\n", err);
}

}  // namespace

int main() {
  numeric_equivalence();
  closed_loop();
  std::printf("%d passed, %d failed\n", passed, failed);
  return failed == 0 ? 0 : 1;
}
