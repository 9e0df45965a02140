// A generated high-gain or Kalman-like theta observer header, in float and double: derivative()
// against GiNaC reference values (hgkt_reference.cpp), no heap in step(), and (when
// OBSYNTH_CLOSED_LOOP) a zero-order-hold closed loop with the plant integrated here by RK4.
#include <cmath>
#include <cstdio>

#include OBSYNTH_HGKT_HEADER
#include OBSYNTH_REFERENCE_HEADER
#include "alloc_counter.hpp"

namespace {

int failures = 0;

void check(bool ok, const char* what, int k, int i, double got, double want) {
  if (ok) return;
  ++failures;
  std::printf("FAIL %s point %d entry %d: got %.17g want %.17g\n", what, k, i, got, want);
}

template <class Scalar>
void equivalence(double rel) {
  using Obs = OBSYNTH_HGKT_CLASS<Scalar>;
  Obs obs;
  for (int k = 0; k < ref::kPoints; ++k) {
    typename Obs::ObserverState w, dw;
    typename Obs::Input u;
    typename Obs::Output y;
    for (int i = 0; i < Obs::nw; ++i) w(i) = Scalar(ref::w[k][i]);
    for (int j = 0; j < Obs::m; ++j) u(j) = Scalar(ref::u[k][j]);
    y(0) = Scalar(ref::y[k][0]);
    const auto st = obs.derivative(w, u, y, dw);
    check(st == obsynth::Status::ok, "status", k, -1, 0, 0);
    double scale = 1;
    for (int i = 0; i < Obs::nw; ++i) scale = std::fmax(scale, std::fabs(ref::dw[k][i]));
    for (int i = 0; i < Obs::nw; ++i)
      check(std::fabs(double(dw(i)) - ref::dw[k][i]) <= rel * scale, "derivative", k, i,
            double(dw(i)), ref::dw[k][i]);
  }
}

#ifdef OBSYNTH_CLOSED_LOOP
// Plant x' = f + g with the header's own model maps (checked against GiNaC through the
// derivative above), u = OBSYNTH_U_AMPL sin t, x0 = 1, xh0 = 0; the observer steps with u, y
// held over dt. Returns the final max error; counts allocations inside step().
template <class Scalar>
double closed_loop(std::size_t& allocations) {
  using Obs = OBSYNTH_HGKT_CLASS<Scalar>;
  using F = typename Obs::F;
  using State = typename Obs::State;
  using Input = typename Obs::Input;
  Obs obs;
  State x = State::Constant(Scalar(1));
  obs.reset(State::Zero());
  const double dt = 1e-3;
  auto field = [](const State& s, const Input& u) {
    State a, b;
    F::f(s, a);
    F::g(s, u, b);
    return State(a + b);
  };
  for (int k = 0; k < int(OBSYNTH_T_END / dt); ++k) {
    const double t = k * dt;
    Input u, uh;
    for (int j = 0; j < Obs::m; ++j) u(j) = Scalar(OBSYNTH_U_AMPL * std::sin(t));
    for (int j = 0; j < Obs::m; ++j) uh(j) = Scalar(OBSYNTH_U_AMPL * std::sin(t + dt / 2));
    typename Obs::Output y;
    F::h(x, y);
    obsynth::test::AllocationCounter counter;
    const auto st = obs.step(Scalar(dt), u, y);
    allocations += counter.allocations();
    if (st != obsynth::Status::ok) return 1e30;
    Input u1;
    for (int j = 0; j < Obs::m; ++j) u1(j) = Scalar(OBSYNTH_U_AMPL * std::sin(t + dt));
    const State k1 = field(x, u);
    const State k2 = field(State(x + Scalar(dt / 2) * k1), uh);
    const State k3 = field(State(x + Scalar(dt / 2) * k2), uh);
    const State k4 = field(State(x + Scalar(dt) * k3), u1);
    x += Scalar(dt / 6) * (k1 + Scalar(2) * k2 + Scalar(2) * k3 + k4);
  }
  return double((x - obs.estimate()).cwiseAbs().maxCoeff());
}
#endif

}  // namespace

int main() {
  equivalence<double>(1e-10);
  equivalence<float>(2e-5);
#ifdef OBSYNTH_CLOSED_LOOP
  std::size_t allocations = 0;
  const double ed = closed_loop<double>(allocations);
  const double ef = closed_loop<float>(allocations);
  std::printf("closed loop: final error %.3e (double), %.3e (float), %zu allocations\n", ed, ef,
              allocations);
  if (!(ed < OBSYNTH_TOL_DOUBLE) || !(ef < OBSYNTH_TOL_FLOAT) || allocations != 0) ++failures;
#endif
  std::printf("%s: %d failures\n", OBSYNTH_HGKT_HEADER, failures);
  return failures == 0 ? 0 : 1;
}
