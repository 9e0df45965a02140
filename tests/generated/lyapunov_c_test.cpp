// Tests of one generated C99 Thau or Kou observer pair (--language c), compiled as C under the
// strict flags and driven from C++: numeric equivalence of f, g, h and the observer field with
// GiNaC's values (lyapunov_reference.cpp), and the firmware step() converging in closed loop
// from several initial errors, in the pair's scalar type.
#include <cmath>
#include <cstdio>

#include OBSYNTH_C_HEADER
#include OBSYNTH_REFERENCE_HEADER

#define OBSYNTH_CAT2(a, b) a##_##b
#define OBSYNTH_CAT(a, b) OBSYNTH_CAT2(a, b)
#define C_(name) OBSYNTH_CAT(OBSYNTH_C_PREFIX, name)

using Scalar = C_(scalar);
constexpr int n = C_(n);
constexpr int m = C_(m);
constexpr int p = C_(p);

#if OBSYNTH_HAS_PARAMS
#define PRM(q) &q,
using Params = C_(params);
#else
#define PRM(q)
struct Params {};
#endif

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

Params default_params() {
  Params q{};
#if OBSYNTH_HAS_PARAMS
  C_(params_init)(&q);
#endif
  return q;
}

void load(Scalar* v, const double* data, int size) {
  for (int i = 0; i < size; ++i) v[i] = static_cast<Scalar>(data[i]);
}

void compare(const Scalar* got, const double* want, int size, double tol, const char* what) {
  double scale = 1;
  for (int i = 0; i < size; ++i) scale = std::fmax(scale, std::fabs(want[i]));
  for (int i = 0; i < size; ++i)
    expect(std::fabs(static_cast<double>(got[i]) - want[i]) <= tol * scale, what,
           static_cast<double>(got[i]), want[i]);
}

void numeric_equivalence(double tol) {
  [[maybe_unused]] const Params prm = default_params();
  for (int k = 0; k < ref::kPoints; ++k) {
    Scalar x[n], out[n], u[m > 0 ? m : 1] = {}, y[p], hy[p];
    load(x, ref::x[k], n);
    if (m > 0) load(u, ref::u[k], m);
    load(y, ref::y[k], p);
    C_(f)(x, PRM(prm) out);
    compare(out, ref::f[k], n, tol, "f");
    C_(g)(x, u, PRM(prm) out);
    compare(out, ref::g[k], n, tol, "g");
    C_(h)(x, PRM(prm) hy);
    compare(hy, ref::h[k], p, tol, "h");
    C_(x_rhs)(x, u, y, PRM(prm) out);
    compare(out, ref::rhs[k], n, tol, "x_rhs = f + g + L (h - y)");
  }
}

double input(double t) {
  return OBSYNTH_INPUT_AMPLITUDE * std::sin(t);
}

void plant_rhs(const double* x, double t, double* dx) {
  [[maybe_unused]] const Params prm = default_params();
  Scalar xs[n], a[n], b[n], u[m > 0 ? m : 1] = {};
  load(xs, x, n);
  if (m > 0) u[0] = static_cast<Scalar>(input(t));
  C_(f)(xs, PRM(prm) a);
  C_(g)(xs, u, PRM(prm) b);
  for (int i = 0; i < n; ++i) dx[i] = static_cast<double>(a[i]) + static_cast<double>(b[i]);
}

// Returns the largest error over the last second; the start is as in lyapunov_test.cpp.
double closed_loop_zoh(int k, double dt, double* e0) {
  [[maybe_unused]] const Params prm = default_params();
  C_(observer) obs;
  C_(init)(&obs);
  double x[n];
  Scalar xh0[n];
  *e0 = 0;
  for (int i = 0; i < n; ++i) {
    const double c = (ref::region_lo[i] + ref::region_hi[i]) / 2;
    const double w = (ref::region_hi[i] - ref::region_lo[i]) / 2;
    const double sx = ((k + i) % 3 - 1) * 0.2, se = ((k * 7 + i * 3) % 5 - 2) * 0.2 + 0.1;
    x[i] = c + sx * w;
    xh0[i] = static_cast<Scalar>(x[i] + se * w);
    *e0 = std::fmax(*e0, std::fabs(se * w));
  }
  expect(C_(reset)(&obs, xh0) == C_(ok), "reset: status");
  const double t_end = 40;  // long enough for the transient to fall below the ZOH floor
  const int steps = static_cast<int>(t_end / dt + 0.5);
  double floor = 0;
  for (int s = 0; s < steps; ++s) {
    const double t = s * dt;
    Scalar u[m > 0 ? m : 1] = {}, xs[n], y[p];
    if (m > 0) u[0] = static_cast<Scalar>(input(t));
    load(xs, x, n);
    C_(h)(xs, PRM(prm) y);
    expect(C_(step)(&obs, static_cast<Scalar>(dt), u, y) == C_(ok), "zoh: step status");
    double k1[n], k2[n], k3[n], k4[n], v[n];
    plant_rhs(x, t, k1);
    for (int i = 0; i < n; ++i) v[i] = x[i] + dt / 2 * k1[i];
    plant_rhs(v, t + dt / 2, k2);
    for (int i = 0; i < n; ++i) v[i] = x[i] + dt / 2 * k2[i];
    plant_rhs(v, t + dt / 2, k3);
    for (int i = 0; i < n; ++i) v[i] = x[i] + dt * k3[i];
    plant_rhs(v, t + dt, k4);
    for (int i = 0; i < n; ++i) x[i] += dt / 6 * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i]);
    if (t >= t_end - 1)
      for (int i = 0; i < n; ++i)
        floor = std::fmax(floor, std::fabs(x[i] - static_cast<double>(obs.xh[i])));
  }
  return floor;
}

}  // namespace

int main() {
  const bool single = sizeof(Scalar) == sizeof(float);
  numeric_equivalence(single ? 1e-5 : 1e-12);
  for (int k = 0; k < 4; ++k) {
    double e0 = 0;
    const double e = closed_loop_zoh(k, 1e-3, &e0);
    expect(e < 5e-3 && e < 0.05 * e0, "zoh: error from e0 down below 5e-3 and 5% of e0", e, e0);
    std::printf("start %d (C, %s): |e0| %.3f, final error %.3e\n", k, single ? "float" : "double",
                e0, e);
  }
  std::printf("%s (C, %s): %d passed, %d failed\n", OBSYNTH_NAME, single ? "float" : "double",
              passed, failed);
  return failed == 0 ? 0 : 1;
}
