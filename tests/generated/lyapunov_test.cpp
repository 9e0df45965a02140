// Tests of one generated Thau or Kou observer header (C++), under the generated-code contract
// flags: numeric equivalence of f, g, h and the observer field with GiNaC's values
// (lyapunov_reference.cpp), in double and float; closed loop (plant and observer as one ODE)
// from several initial errors in which V = e' P e decays at least at the certified rate while
// x and xh stay in the certified region; the firmware step() in double and float converging
// with zero allocations.
// Macros: OBSYNTH_HEADER, OBSYNTH_REFERENCE_HEADER, OBSYNTH_NS, OBSYNTH_CLASS, OBSYNTH_FUNCTIONS,
// OBSYNTH_HAS_PARAMS, OBSYNTH_INPUT_AMPLITUDE, OBSYNTH_NAME.
// The generated header is the first include: it must compile alone. Every member of its class
// templates is instantiated for float and double below (compiled with EIGEN_NO_MALLOC).
#include OBSYNTH_HEADER
#include OBSYNTH_REFERENCE_HEADER

#include <cmath>
#include <cstdio>

#include "alloc_counter.hpp"

template class obsynth_gen::OBSYNTH_NS::OBSYNTH_CLASS<float>;
template class obsynth_gen::OBSYNTH_NS::OBSYNTH_CLASS<double>;
template struct obsynth_gen::OBSYNTH_NS::OBSYNTH_FUNCTIONS<float>;
template struct obsynth_gen::OBSYNTH_NS::OBSYNTH_FUNCTIONS<double>;

namespace gen = obsynth_gen::OBSYNTH_NS;

#if OBSYNTH_HAS_PARAMS
#define PRM(p) p,
template <class Scalar>
using Params = gen::ModelParams<Scalar>;
#else
#define PRM(p)
template <class Scalar>
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

template <class Scalar>
using F = gen::OBSYNTH_FUNCTIONS<Scalar>;

template <class Scalar, class V>
void load(V& v, const double* data) {
  for (int i = 0; i < v.size(); ++i) v(i) = static_cast<Scalar>(data[i]);
}

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
  [[maybe_unused]] const Params<Scalar> prm{};
  for (int k = 0; k < ref::kPoints; ++k) {
    typename S::State x, out;
    typename S::Input u;
    typename S::Output y, hy;
    load<Scalar>(x, ref::x[k]);
    if (gen::m > 0) load<Scalar>(u, ref::u[k]);
    load<Scalar>(y, ref::y[k]);
    S::f(x, PRM(prm) out);
    compare(out, ref::f[k], gen::n, tol, "f");
    S::g(x, u, PRM(prm) out);
    compare(out, ref::g[k], gen::n, tol, "g");
    S::h(x, PRM(prm) hy);
    compare(hy, ref::h[k], gen::p, tol, "h");
    S::x_rhs(x, u, y, PRM(prm) out);
    compare(out, ref::rhs[k], gen::n, tol, "x_rhs = f + g + L (h - y)");
    gen::OBSYNTH_CLASS<Scalar> obs;
    obs.derivative(x, u, y, out);
    compare(out, ref::rhs[k], gen::n, tol, "derivative()");
  }
}

using D = F<double>;
using Obs = gen::OBSYNTH_CLASS<double>;
static_assert(obsynth::is_observer_v<gen::OBSYNTH_CLASS<double>>, "observer interface (double)");
static_assert(obsynth::is_observer_v<gen::OBSYNTH_CLASS<float>>, "observer interface (float)");

double input(double t) {
  return OBSYNTH_INPUT_AMPLITUDE * std::sin(t);
}

void plant_rhs(const D::State& x, double t, D::State& dx) {
  [[maybe_unused]] const Params<double> prm{};
  D::State a, b;
  D::Input u;
  if (gen::m > 0) u(0) = input(t);
  D::f(x, PRM(prm) a);
  D::g(x, u, PRM(prm) b);
  dx = a + b;
}

double V(const D::State& e) {
  double v = 0;
  for (int i = 0; i < gen::n; ++i)
    for (int j = 0; j < gen::n; ++j) v += e(i) * ref::P[i * gen::n + j] * e(j);
  return v;
}

bool in_region(const D::State& x) {
  for (int i = 0; i < gen::n; ++i)
    if (x(i) < ref::region_lo[i] || x(i) > ref::region_hi[i]) return false;
  return true;
}

// Start k: x0 and xh0 in the middle of the region, errors of different signs and sizes.
void start(int k, D::State& x0, D::State& xh0) {
  for (int i = 0; i < gen::n; ++i) {
    const double c = (ref::region_lo[i] + ref::region_hi[i]) / 2;
    const double w = (ref::region_hi[i] - ref::region_lo[i]) / 2;
    const double sx = ((k + i) % 3 - 1) * 0.2, se = ((k * 7 + i * 3) % 5 - 2) * 0.2 + 0.1;
    x0(i) = c + sx * w;
    xh0(i) = x0(i) + se * w;
  }
}

// Plant and observer as one ODE (RK4, u and y exact at every stage).
void closed_loop_continuous(int k) {
  D::State x, xh0;
  start(k, x, xh0);
  Obs obs;
  obs.reset(xh0);
  using Big = Eigen::Matrix<double, 2 * gen::n, 1>;
  auto rhs = [&](double t, const Big& v, Big& dv) {
    const D::State xv = v.head<gen::n>(), sv = v.tail<gen::n>();
    D::State dx, ds;
    plant_rhs(xv, t, dx);
    D::Input u;
    if (gen::m > 0) u(0) = input(t);
    D::Output y;
    [[maybe_unused]] const Params<double> prm{};
    D::h(xv, PRM(prm) y);
    obs.derivative(sv, u, y, ds);
    dv << dx, ds;
  };
  Big v;
  v << x, obs.observer_state();
  const double dt = 1e-3, t_end = 12;
  const double V0 = V(obs.observer_state() - x);
  bool inside = true, decays = true;
  double worst_ratio = 0;
  const int steps = static_cast<int>(t_end / dt + 0.5);
  for (int s = 0; s < steps; ++s) {
    const double t = s * dt;
    Big k1, k2, k3, k4;
    rhs(t, v, k1);
    rhs(t + dt / 2, v + dt / 2 * k1, k2);
    rhs(t + dt / 2, v + dt / 2 * k2, k3);
    rhs(t + dt, v + dt * k3, k4);
    v += dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
    const D::State xs = v.head<gen::n>(), xh = v.tail<gen::n>();
    inside = inside && in_region(xs) && in_region(xh);
    const double bound = V0 * std::exp(-ref::kVRate * (t + dt));
    if (V(xh - xs) > bound * (1 + 1e-6) + 1e-24) decays = false;
    worst_ratio = std::fmax(worst_ratio, V(xh - xs) / bound);
  }
  obs.set_observer_state(v.tail<gen::n>());
  const double e_end = (v.head<gen::n>() - obs.estimate()).cwiseAbs().maxCoeff();
  expect(inside, "closed loop: x and xh stay in the certified region");
  expect(decays, "closed loop: V decays at least at the certified rate", worst_ratio, 1);
  const double e_start = (xh0 - x).cwiseAbs().maxCoeff();
  // The certificate bounds the rate from below; the actual rate is set by the (moderate) gains.
  expect(e_end < 1e-2 * e_start, "closed loop: error down by 1e-2 after 12 s", e_end / e_start,
         1e-2);
  std::printf(
      "start %d: |e(0)| %.3f, final error %.3e, max V(t)/bound %.3f (certified V rate %.4f)\n", k,
      (xh0 - x).norm(), e_end, worst_ratio, ref::kVRate);
}

// The firmware step(): u, y held over each step.
template <class Scalar>
double closed_loop_zoh(double dt, std::size_t* allocations) {
  using S = F<Scalar>;
  gen::OBSYNTH_CLASS<Scalar> obs;
  D::State x, xh0;
  start(0, x, xh0);
  obs.reset(xh0.cast<Scalar>());
  const double t_end = 40;  // long enough for the transient to fall below the ZOH floor
  const int steps = static_cast<int>(t_end / dt + 0.5);
  obsynth::test::AllocationCounter counter;
  std::size_t allocs = 0;
  double floor = 0;
  for (int k = 0; k < steps; ++k) {
    const double t = k * dt;
    typename S::Input u;
    if (gen::m > 0) u(0) = static_cast<Scalar>(input(t));
    [[maybe_unused]] const Params<double> prm{};
    D::Output y;
    D::h(x, PRM(prm) y);
    const typename S::Output ys = y.cast<Scalar>();
    counter.restart();
    obs.step(static_cast<Scalar>(dt), u, ys);
    allocs += counter.allocations();
    D::State k1, k2, k3, k4;
    plant_rhs(x, t, k1);
    plant_rhs(x + dt / 2 * k1, t + dt / 2, k2);
    plant_rhs(x + dt / 2 * k2, t + dt / 2, k3);
    plant_rhs(x + dt * k3, t + dt, k4);
    x += dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
    if (t >= t_end - 1)
      floor = std::fmax(floor, (x - obs.estimate().template cast<double>()).cwiseAbs().maxCoeff());
  }
  if (allocations) *allocations = allocs;
  expect(obs.status() == obsynth::Status::ok, "zoh: status ok");
  return floor;
}

}  // namespace

int main() {
  numeric_equivalence<double>(1e-12);
  numeric_equivalence<float>(1e-5);
  for (int k = 0; k < 4; ++k) closed_loop_continuous(k);
  std::size_t allocs = 1;
  const double e1 = closed_loop_zoh<double>(2e-3, &allocs);
  const double e2 = closed_loop_zoh<double>(1e-3, nullptr);
  const double ef = closed_loop_zoh<float>(1e-3, nullptr);
  expect(allocs == 0, "zero allocations in step()", static_cast<double>(allocs), 0);
  expect(e2 < 5e-3, "zoh double: floor below 5e-3 at dt = 1e-3", e2, 5e-3);
  expect(e2 < 0.7 * e1 || e2 < 1e-9, "zoh double: floor first order in dt", e2 / e1, 0.5);
  expect(ef < e2 + 1e-3, "zoh float: floor within 1e-3 of double's", ef, e2 + 1e-3);
  std::printf("zoh floor: double %.3e (dt 2e-3), %.3e (dt 1e-3), float %.3e; malloc hooks %s\n", e1,
              e2, ef, obsynth::test::malloc_hooks_active() ? "on" : "off");
  std::printf("%s: %d passed, %d failed\n", OBSYNTH_NAME, passed, failed);
  return failed == 0 ? 0 : 1;
}
