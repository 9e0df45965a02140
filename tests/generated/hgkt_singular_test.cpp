// The generated high-gain observer of tests/models/hgkt_cubic.sym (x1' = x2^3, x2' = -x1, y = x1;
// O = diag(1, 3 x2^2), singular on x2 = 0), in float and double, and its C99 pair when
// OBSYNTH_C_HEADER is given:
// 1. started on the singular set x2 = 0, the step is rejected with Status::singular and the
//    state kept; started off the set, the same step is ok;
// 2. closed loop from x0 = (1, 1), xh0 = (0.5, 0.5), the firmware step with y held over
//    dt = 1e-3 and the plant integrated here (RK4 in double, hand-written: x1^2 + x2^4 / 2 = 3/2,
//    so the plant crosses x2 = 0 every ~2.8 s with |x2'| = |x1| = 1.2247). The LU solve refuses
//    O(xh) once its pivot 3 xh2^2 is at most sqrt(eps) (eps of the scalar), i.e. an RK4 stage
//    with |xh2| <= sqrt(sqrt(eps) / 3) = 7.05e-5 (double), 0.0107 (float). So the run ends with
//    Status::singular at a crossing of x2 = 0: the last accepted xh2 is within a step
//    (|xh2'| < 5) of that window, the plant's x2 within 0.01 |x1| + 1e-3 of 0; before it every
//    estimate is finite, in the domain box [-2, 2]^2 and (after 0.5 s) within 0.1 of the plant,
//    and the status comes before t = 17.7 (under the old limit, pivot <= 2 eps, the double
//    estimate jumped to (-44829, -215) at t = 17.77 with Status::ok).
#include <cmath>
#include <cstdio>
#include <limits>

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

template <class Scalar>
int start_on_the_set() {
  using Obs = obsynth_gen::hgkt_cubic::HgktCubicHighGain<Scalar>;
  int failures = 0;
  Obs obs;
  typename Obs::State x0;
  x0 << Scalar(0.5), Scalar(0);
  obs.reset(x0);
  typename Obs::Input u;
  typename Obs::Output y;
  y << Scalar(1);
  const auto st = obs.step(Scalar(1e-3), u, y);
  if (st != obsynth::Status::singular || obs.status() != obsynth::Status::singular) ++failures;
  if (!(obs.estimate() == x0)) ++failures;  // state kept
  x0 << Scalar(0.5), Scalar(0.5);
  obs.reset(x0);
  if (obs.step(Scalar(1e-3), u, y) != obsynth::Status::ok) ++failures;
  return failures;
}

void plant(const double* x, double* dx) {
  dx[0] = x[1] * x[1] * x[1];
  dx[1] = -x[0];
}

void plant_rk4(double* x, double dt) {
  double k1[2], k2[2], k3[2], k4[2], t[2];
  plant(x, k1);
  for (int i = 0; i < 2; ++i) t[i] = x[i] + dt / 2 * k1[i];
  plant(t, k2);
  for (int i = 0; i < 2; ++i) t[i] = x[i] + dt / 2 * k2[i];
  plant(t, k3);
  for (int i = 0; i < 2; ++i) t[i] = x[i] + dt * k3[i];
  plant(t, k4);
  for (int i = 0; i < 2; ++i) x[i] += dt / 6 * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i]);
}

// step(y, xh) returns 0 (ok), 1 (singular) or 2 (anything else) and writes the estimate.
template <class Scalar, class Step>
int crossing(const char* what, Step&& step) {
  const double dt = 1e-3;
  const double eps = double(std::numeric_limits<Scalar>::epsilon());
  const double window = std::sqrt(std::sqrt(eps) / 3);
  double x[2] = {1, 1}, xh[2] = {0.5, 0.5};
  for (long k = 0; k < 20000; ++k) {
    const double t = double(k) * dt;
    double next[2];
    const int st = step(x[0], next);
    if (st == 1) {
      // Refused: the last accepted estimate xh is kept; the plant is at x(t).
      const bool near_set = std::fabs(xh[1]) <= window + 5 * dt;
      const bool plant_crossing = std::fabs(x[1]) <= 0.01 * std::fabs(x[0]) + 1e-3;
      const bool early = t < 17.7;
      std::printf("%s: Status::singular at t = %.3f, xh = (%g, %g), x = (%g, %g)%s%s%s\n", what, t,
                  xh[0], xh[1], x[0], x[1], near_set ? "" : " [xh2 not near the window]",
                  plant_crossing ? "" : " [plant not at x2 = 0]", early ? "" : " [too late]");
      return near_set && plant_crossing && early ? 0 : 1;
    }
    if (st != 0) {
      std::printf("%s: unexpected status at t = %.3f\n", what, t);
      return 1;
    }
    plant_rk4(x, dt);
    for (int i = 0; i < 2; ++i) {
      xh[i] = next[i];
      const bool bad = !std::isfinite(xh[i]) || std::fabs(xh[i]) > 2 ||
                       (t + dt >= 0.5 && std::fabs(xh[i] - x[i]) > 0.1);
      if (bad) {
        std::printf("%s: estimate (%g, %g) against x = (%g, %g) at t = %.3f with Status::ok\n",
                    what, xh[0], xh[1], x[0], x[1], t + dt);
        return 1;
      }
    }
  }
  std::printf("%s: no status in 20 s\n", what);
  return 1;
}

template <class Scalar>
int crossing_cxx(const char* what) {
  using Obs = obsynth_gen::hgkt_cubic::HgktCubicHighGain<Scalar>;
  Obs obs;
  typename Obs::State x0;
  x0 << Scalar(0.5), Scalar(0.5);
  obs.reset(x0);
  typename Obs::Input u;
  return crossing<Scalar>(what, [&](double y1, double* xh) {
    typename Obs::Output y;
    y << Scalar(y1);
    const auto st = obs.step(Scalar(1e-3), u, y);
    xh[0] = double(obs.estimate()(0));
    xh[1] = double(obs.estimate()(1));
    if (st == obsynth::Status::singular) return 1;
    return st == obsynth::Status::ok ? 0 : 2;
  });
}

#ifdef OBSYNTH_C_HEADER
int crossing_c() {
  using Scalar = C_(_scalar);
  C_(_observer) o;
  C_(_init)(&o);
  const Scalar xh0[2] = {Scalar(0.5), Scalar(0.5)};
  if (C_(_reset)(&o, xh0) != C_(_ok)) return 1;
  const char* what = sizeof(Scalar) == sizeof(double) ? "C double" : "C float";
  return crossing<Scalar>(what, [&](double y1, double* xh) {
    const Scalar y[1] = {Scalar(y1)};
    const auto st = C_(_step)(&o, Scalar(1e-3), nullptr, y);
    xh[0] = double(o.xh[0]);
    xh[1] = double(o.xh[1]);
    if (st == C_(_singular)) return 1;
    return st == C_(_ok) ? 0 : 2;
  });
}
#endif

}  // namespace

int main() {
  int failures = start_on_the_set<double>() + start_on_the_set<float>();
  failures += crossing_cxx<double>("C++ double") + crossing_cxx<float>("C++ float");
#ifdef OBSYNTH_C_HEADER
  failures += crossing_c();
#endif
  std::printf("hgkt_cubic singular O: %d failures\n", failures);
  return failures == 0 ? 0 : 1;
}
