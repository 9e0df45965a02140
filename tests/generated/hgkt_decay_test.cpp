// The generated high-gain observer of tests/models/hgkt_cubic_decay.sym (x1' = x2^3, x2' = -x2,
// y = x1; O = diag(1, 3 x2^2), singular on x2 = 0, which the plant approaches as x2 = e^-t)
// in double, C++ and (with OBSYNTH_C_HEADER) the C99 pair. Closed loop from x0 = (0, 1),
// xh0 = (0.5, 0.5), the firmware step with y held over dt = 1e-3, plant by a hand-written RK4.
// The LU solve refuses O(xh) once its pivot 3 xh2^2 is at most sqrt(eps) = 2^-26, i.e. at
// xh2 <= sqrt(2^-26 / 3) = 7.0477e-5. The estimate tracks the plant (to 2e-8 there), so the
// step is refused when an RK4 stage reaches that level: x2 = e^-t = 7.0477e-5 at
// t = ln(1 / 7.0477e-5) = 9.5602, and the step starting at t = 9.559 or 9.560 is refused (its
// last stage is at t + dt). Before that: Status::ok, finite, tracking after t = 3 (x1 to 1e-6,
// x2 to 1e-3 |x2|, the zero-order-hold lag). (With
// the old limit, a pivot <= 2 eps, the double run stalled at xh2 = -1.3e-5 with Status::ok
// while x2 -> 1e-13.)
#include <cmath>
#include <cstdio>

#include OBSYNTH_HGKT_HEADER
#ifdef OBSYNTH_C_HEADER
extern "C" {
#include OBSYNTH_C_HEADER
}
#define CAT2(a, b) a##b
#define CAT(a, b) CAT2(a, b)
#define C_(name) CAT(OBSYNTH_C_PREFIX, name)
#endif

namespace {

void plant_rk4(double* x, double dt) {
  auto f = [](const double* v, double* d) {
    d[0] = v[1] * v[1] * v[1];
    d[1] = -v[1];
  };
  double k1[2], k2[2], k3[2], k4[2], t[2];
  f(x, k1);
  for (int i = 0; i < 2; ++i) t[i] = x[i] + dt / 2 * k1[i];
  f(t, k2);
  for (int i = 0; i < 2; ++i) t[i] = x[i] + dt / 2 * k2[i];
  f(t, k3);
  for (int i = 0; i < 2; ++i) t[i] = x[i] + dt * k3[i];
  f(t, k4);
  for (int i = 0; i < 2; ++i) x[i] += dt / 6 * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i]);
}

// step(y, xh) returns 0 (ok), 1 (singular) or 2 (anything else) and writes the estimate.
template <class Step>
int decay(const char* what, Step&& step) {
  const double dt = 1e-3, t_hand = std::log(1 / std::sqrt(std::ldexp(1.0, -26) / 3));
  double x[2] = {0, 1}, xh[2] = {0.5, 0.5};
  for (long k = 0; k < 30000; ++k) {
    const double t = double(k) * dt;
    double next[2];
    const int st = step(x[0], next);
    if (st == 1) {
      const bool on_time = t >= t_hand - 2 * dt && t <= t_hand + dt;
      std::printf("%s: Status::singular at t = %.3f (predicted %.4f - dt), xh2 = %g, x2 = %g%s\n",
                  what, t, t_hand, xh[1], x[1], on_time ? "" : " [not on time]");
      return on_time ? 0 : 1;
    }
    if (st != 0) {
      std::printf("%s: unexpected status at t = %.3f\n", what, t);
      return 1;
    }
    plant_rk4(x, dt);
    for (int i = 0; i < 2; ++i) {
      xh[i] = next[i];
      // Zero-order hold: y is held over the step, the estimate lags by about dt / 2 |x'|, and
      // |x2'| = |x2| (measured: 5e-4 |x2|); x1 is nearly constant.
      const double tol = i == 0 ? 1e-6 : 1e-3 * std::fabs(x[1]) + 1e-9;
      if (!std::isfinite(xh[i]) || (t + dt >= 3 && std::fabs(xh[i] - x[i]) > tol)) {
        std::printf("%s: estimate (%g, %g) against x = (%g, %g) at t = %.3f with Status::ok\n",
                    what, xh[0], xh[1], x[0], x[1], t + dt);
        return 1;
      }
    }
  }
  std::printf("%s: no status in 30 s, xh2 = %g, x2 = %g\n", what, xh[1], x[1]);
  return 1;
}

int decay_cxx() {
  using Obs = obsynth_gen::hgkt_cubic_decay::HgktCubicDecayHighGain<double>;
  Obs obs;
  Obs::State x0;
  x0 << 0.5, 0.5;
  obs.reset(x0);
  Obs::Input u;
  return decay("C++ double", [&](double y1, double* xh) {
    Obs::Output y;
    y << y1;
    const auto st = obs.step(1e-3, u, y);
    xh[0] = obs.estimate()(0);
    xh[1] = obs.estimate()(1);
    if (st == obsynth::Status::singular) return 1;
    return st == obsynth::Status::ok ? 0 : 2;
  });
}

#ifdef OBSYNTH_C_HEADER
int decay_c() {
  C_(_observer) o;
  C_(_init)(&o);
  const double xh0[2] = {0.5, 0.5};
  if (C_(_reset)(&o, xh0) != C_(_ok)) return 1;
  return decay("C double", [&](double y1, double* xh) {
    const double y[1] = {y1};
    const auto st = C_(_step)(&o, 1e-3, nullptr, y);
    xh[0] = o.xh[0];
    xh[1] = o.xh[1];
    if (st == C_(_singular)) return 1;
    return st == C_(_ok) ? 0 : 2;
  });
}
#endif

}  // namespace

int main() {
  int failures = decay_cxx();
#ifdef OBSYNTH_C_HEADER
  failures += decay_c();
#endif
  std::printf("hgkt_cubic_decay: %d failures\n", failures);
  return failures == 0 ? 0 : 1;
}
