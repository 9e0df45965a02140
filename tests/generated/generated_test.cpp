// Tests of one generated canonical observer header (and its perfect observer, when built):
// numeric equivalence with GiNaC's values, closed loop at the designed rate, zero-order-hold
// firmware steps in double and float, zero allocations per step.
// Built per model with OBSYNTH_NS, OBSYNTH_CLASS and the headers given as macros, under the
// generated-code contract flags (-Werror -Wconversion -Wdouble-promotion -fno-exceptions ...).
#include <cmath>
#include <cstdio>

#include OBSYNTH_CANONICAL_HEADER
#include OBSYNTH_REFERENCE_HEADER
#include "alloc_counter.hpp"

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
using F = gen::CanonicalFunctions<Scalar>;

template <class Scalar, class V>
void load(V& v, const double* data) {
  for (int i = 0; i < v.size(); ++i) v(i) = static_cast<Scalar>(data[i]);
}

// |got - want| <= tol * max(1, max |want|) over the vector.
template <class V>
void compare(const V& got, const double* want, int size, double tol, const char* what) {
  double scale = 1;
  for (int i = 0; i < size; ++i) scale = std::fmax(scale, std::fabs(want[i]));
  for (int i = 0; i < size; ++i) {
    const double g = static_cast<double>(got(i));
    expect(std::fabs(g - want[i]) <= tol * scale, what, g, want[i]);
  }
}

template <class Scalar>
void numeric_equivalence(double tol) {
  using S = F<Scalar>;
  for (int k = 0; k < ref::kPoints; ++k) {
    typename S::State x, out, z;
    typename S::Input u;
    typename S::Output y;
    typename S::Frame fr;
    load<Scalar>(x, ref::x[k]);
    if (gen::m > 0) load<Scalar>(u, ref::u[k]);
    S::f(x, out);
    compare(out, ref::f[k], gen::n, tol, "f");
    S::g(x, u, out);
    compare(out, ref::g[k], gen::n, tol, "g");
    S::h(x, y);
    compare(y, ref::h[k], 1, tol, "h");
    S::l(u, y, out);
    compare(out, ref::l[k], gen::n, tol, "l");
#if OBSYNTH_HAS_T
    S::T(x, out);
    compare(out, ref::T[k], gen::n, tol, "T");
#endif
#if OBSYNTH_HAS_TINV
    load<Scalar>(z, ref::z[k]);
    S::T_inverse(z, out);
    compare(out, ref::Tinv[k], gen::n, tol, "T_inverse");
#endif
#if OBSYNTH_HAS_FRAME
    S::frame(x, fr);
    for (int c = 0; c < gen::n; ++c)
      for (int r = 0; r < gen::n; ++r) {
        const double want = ref::frame[k][c * gen::n + r];
        expect(std::fabs(static_cast<double>(fr(r, c)) - want) <= tol * std::fmax(1.0, std::fabs(want)), "frame",
               static_cast<double>(fr(r, c)), want);
      }
#endif
#if OBSYNTH_Z_REALISATION
    S::step_constant(u, y, out);
    compare(out, ref::step_constant[k], gen::n, tol, "step_constant");
    typename S::State c = out;
    load<Scalar>(z, ref::z[k]);
    S::z_rhs(z, c, out);
    compare(out, ref::z_rhs[k], gen::n, tol, "z_rhs");
#else
    typename S::Output yy;
    yy(0) = y(0) + static_cast<Scalar>(0.1);
    S::x_rhs(x, u, yy, out);
    compare(out, ref::x_rhs[k], gen::n, tol, "x_rhs");
#endif
    (void)z;
    (void)fr;
  }
}

using D = F<double>;
using Obs = gen::OBSYNTH_CLASS<double>;
static_assert(obsynth::is_observer_v<gen::OBSYNTH_CLASS<double>>, "observer interface (double)");
static_assert(obsynth::is_observer_v<gen::OBSYNTH_CLASS<float>>, "observer interface (float)");

[[maybe_unused]] double input(double t) { return OBSYNTH_INPUT_AMPLITUDE * std::sin(t); }

[[maybe_unused]] void plant_rhs(const D::State& x, double u, D::State& dx) {
  D::State a, b;
  D::Input uu;
  if (gen::m > 0) uu(0) = u;
  D::f(x, a);
  D::g(x, uu, b);
  dx = a + b;
}

[[maybe_unused]] double max_error(const D::State& a, const D::State& b) { return (a - b).cwiseAbs().maxCoeff(); }

// Plant and observer as one ODE integrated by RK4 (y and u exact at every stage): the error
// must decay as the designed linear error dynamics.
[[maybe_unused]] void closed_loop_continuous() {
  D::State x, xh0;
  for (int i = 0; i < gen::n; ++i) {
    x(i) = 0.3 * ref::x[0][i];
    xh0(i) = x(i) + (i % 2 ? -0.2 : 0.2);
  }
  Obs obs;
  obs.reset(xh0);
  D::State s = obs.observer_state();
  const double dt = 1e-3;
  const double t_end = OBSYNTH_T_END;
  double e_mid = 0, t_mid = t_end / 2;
  using Big = Eigen::Matrix<double, 2 * gen::n, 1>;
  auto rhs = [](double t, const Big& v, Big& dv) {
    const D::State xv = v.head<gen::n>(), sv = v.tail<gen::n>();
    D::State dx, ds;
    plant_rhs(xv, input(t), dx);
    D::Input u;
    if (gen::m > 0) u(0) = input(t);
    D::Output y;
    D::h(xv, y);
    Obs::derivative(sv, u, y, ds);
    dv << dx, ds;
  };
  Big v;
  v << x, s;
  const int steps = static_cast<int>(t_end / dt + 0.5);
  for (int k = 0; k < steps; ++k) {
    const double t = k * dt;
    Big k1, k2, k3, k4;
    rhs(t, v, k1);
    rhs(t + dt / 2, v + dt / 2 * k1, k2);
    rhs(t + dt / 2, v + dt / 2 * k2, k3);
    rhs(t + dt, v + dt * k3, k4);
    v += dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
    obs.set_observer_state(v.tail<gen::n>());
    if (k + 1 == steps / 2) e_mid = max_error(v.head<gen::n>(), obs.estimate());
  }
  const double e_end = max_error(v.head<gen::n>(), obs.estimate());
  expect(obs.status() == obsynth::Status::ok, "closed loop: status ok");
  expect(e_end < 1e-8, "closed loop: final error below 1e-8", e_end, 1e-8);
  // Designed rate: the slowest pole; allow polynomial factors and the x <- z map (70%).
  const double rate = std::log(e_mid / e_end) / (t_end - t_mid);
  expect(rate > 0.7 * std::fabs(ref::kSlowestPole), "closed loop: decay rate vs slowest pole", rate, std::fabs(ref::kSlowestPole));
  std::printf("closed loop (continuous): error %.3e at t=%.1f, %.3e at t=%.1f, rate %.2f (slowest pole %.2f)\n", e_mid, t_mid,
              e_end, t_end, rate, ref::kSlowestPole);
}

// The firmware step(): u, y held over each step. The error settles at an O(dt) floor.
template <class Scalar>
[[maybe_unused]] double closed_loop_zoh(std::size_t* allocations) {
  using S = F<Scalar>;
  gen::OBSYNTH_CLASS<Scalar> obs;
  D::State x;
  typename S::State xh0;
  for (int i = 0; i < gen::n; ++i) {
    x(i) = 0.3 * ref::x[0][i];
    xh0(i) = static_cast<Scalar>(x(i) + (i % 2 ? -0.2 : 0.2));
  }
  obs.reset(xh0);
  const double dt = 1e-3;
  const int steps = static_cast<int>(OBSYNTH_T_END / dt + 0.5);
  obsynth::test::AllocationCounter counter;
  std::size_t allocs = 0;
  for (int k = 0; k < steps; ++k) {
    const double t = k * dt;
    typename S::Input u;
    if (gen::m > 0) u(0) = static_cast<Scalar>(input(t));
    D::Output y;
    D::h(x, y);
    typename S::Output ys;
    ys(0) = static_cast<Scalar>(y(0));
    counter.restart();
    obs.step(static_cast<Scalar>(dt), u, ys);
    allocs += counter.allocations();
    // plant: RK4 with the exact input
    D::State k1, k2, k3, k4;
    plant_rhs(x, input(t), k1);
    plant_rhs(x + dt / 2 * k1, input(t + dt / 2), k2);
    plant_rhs(x + dt / 2 * k2, input(t + dt / 2), k3);
    plant_rhs(x + dt * k3, input(t + dt), k4);
    x += dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
  }
  if (allocations) *allocations = allocs;
  expect(obs.status() == obsynth::Status::ok, "zoh: status ok");
  return max_error(x, obs.estimate().template cast<double>());
}

}  // namespace

int main() {
  numeric_equivalence<double>(1e-12);
  numeric_equivalence<float>(1e-5);
#if OBSYNTH_CLOSED_LOOP
  closed_loop_continuous();
  std::size_t allocs = 1;
  const double ed = closed_loop_zoh<double>(&allocs);
  expect(allocs == 0, "zero allocations in step()", static_cast<double>(allocs), 0);
  expect(ed < 2e-2, "zoh double: error at the O(dt) floor", ed, 2e-2);
  const double ef = closed_loop_zoh<float>(nullptr);
  expect(ef < 2e-2, "zoh float: error at the O(dt) floor", ef, 2e-2);
  std::printf("zoh: double %.3e, float %.3e; %s allocations counted (malloc hooks %s)\n", ed, ef,
              allocs == 0 ? "no" : "some", obsynth::test::malloc_hooks_active() ? "on" : "off");
#else
  std::printf("closed loop skipped: the plant is not bounded under the test input\n");
#endif
  std::printf("%s: %d passed, %d failed\n", OBSYNTH_NAME, passed, failed);
  return failed == 0 ? 0 : 1;
}
