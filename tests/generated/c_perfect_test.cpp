// A generated C99 perfect observer (--language c) of a constructed chain, compiled as C under
// the strict flags: reconstruct() from the exact output jets (perfect_reference.cpp, GiNaC)
// gives back the state; the firmware step() with its C differentiators agrees step by step
// with the C++ header's (obsynth/differentiator.hpp, an independent implementation of the
// same filter) and tracks the plant once the differentiators' transient has died out.
#include <cmath>
#include <cstdio>

#include OBSYNTH_CXX_HEADER
#include OBSYNTH_C_HEADER
#include OBSYNTH_REFERENCE_HEADER

#define OBSYNTH_CAT2(a, b) a##_##b
#define OBSYNTH_CAT(a, b) OBSYNTH_CAT2(a, b)
#define C_(name) OBSYNTH_CAT(OBSYNTH_C_PREFIX, name)

using Scalar = C_(scalar);
constexpr int n = C_(n);
constexpr int m = C_(m);
using Cxx = obsynth_gen::OBSYNTH_NS::OBSYNTH_CLASS<Scalar>;

namespace {

int passed = 0, failed = 0;

void expect(bool ok, const char* what, double got = 0, double want = 0) {
  if (ok) {
    ++passed;
  } else if (++failed < 20) {
    std::printf("FAIL: %s (got %.17g, want %.17g)\n", what, got, want);
  }
}

#ifndef OBSYNTH_NEWTON
// The chain's jets orders: y up to n-1, inputs held constant in the reference.
void reconstruct_from_exact_jets(double tol) {
  for (int k = 0; k < ref::kPoints; ++k) {
    Scalar yj[n], uj[(m > 0 ? m : 1) * n] = {}, x[n];
    for (int i = 0; i < n; ++i) yj[i] = static_cast<Scalar>(ref::yjet[k][i]);
    for (int j = 0; j < m; ++j) uj[j] = static_cast<Scalar>(ref::u[k][j]);  // column 0
    C_(reconstruct)(yj, uj, x);
    double scale = 1;
    for (int i = 0; i < n; ++i) scale = std::fmax(scale, std::fabs(ref::x[k][i]));
    for (int i = 0; i < n; ++i)
      expect(std::fabs(static_cast<double>(x[i]) - ref::x[k][i]) <= tol * scale, "reconstruct",
             static_cast<double>(x[i]), ref::x[k][i]);
  }
}

#endif

double input(double t) {
  return 0.5 * std::sin(t);
}

void plant_rhs(const double* x, double t, double* dx) {
  Scalar xs[n], a[n], b[n], u[m > 0 ? m : 1] = {};
  for (int i = 0; i < n; ++i) xs[i] = static_cast<Scalar>(x[i]);
  if (m > 0) u[0] = static_cast<Scalar>(input(t));
  C_(f)(xs, a);
  C_(g)(xs, u, b);
  for (int i = 0; i < n; ++i) dx[i] = static_cast<double>(a[i]) + static_cast<double>(b[i]);
}

void plant_step(double* x, double t, double dt) {
  double k1[n], k2[n], k3[n], k4[n], s[n];
  plant_rhs(x, t, k1);
  for (int i = 0; i < n; ++i) s[i] = x[i] + dt / 2 * k1[i];
  plant_rhs(s, t + dt / 2, k2);
  for (int i = 0; i < n; ++i) s[i] = x[i] + dt / 2 * k2[i];
  plant_rhs(s, t + dt / 2, k3);
  for (int i = 0; i < n; ++i) s[i] = x[i] + dt * k3[i];
  plant_rhs(s, t + dt, k4);
  for (int i = 0; i < n; ++i) x[i] += dt / 6 * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i]);
}

// Plant from 0.3 x_ref, both observers from zero, dt = 1e-3 over 3 s. Returns the largest
// tracking error after 1 s (about 100 epsilon: the start-up transient is gone).
double closed_loop(double epsilon, double agree_tol) {
  C_(observer) c;
  C_(init)(&c);
  c.epsilon = static_cast<Scalar>(epsilon);
  Cxx cxx(static_cast<Scalar>(epsilon));
  const Scalar zero[n] = {};
  expect(C_(reset)(&c, zero) == C_(ok), "reset status");
  cxx.reset(Cxx::State::Zero());
  double x[n], worst_agree = 0, worst_track = 0;
  for (int i = 0; i < n; ++i) x[i] = 0.3 * ref::x[0][i];
  const double dt = 1e-3;
  for (int k = 0; k < 3000; ++k) {
    const double t = k * dt;
    plant_step(x, t, dt);
    Scalar xs[n], y[1], u[m > 0 ? m : 1] = {};
    for (int i = 0; i < n; ++i) xs[i] = static_cast<Scalar>(x[i]);
    if (m > 0) u[0] = static_cast<Scalar>(input(t + dt));
    C_(h)(xs, y);
    Cxx::Input ui;
    for (int j = 0; j < m; ++j) ui(j) = u[j];
    Cxx::Output yo;
    yo(0) = y[0];
    const int sc = C_(step)(&c, static_cast<Scalar>(dt), u, y);
    const obsynth::Status scxx = cxx.step(static_cast<Scalar>(dt), ui, yo);
    // Newton may stop at its iteration cap while the jets settle; in float, whether the last
    // iterate meets the tolerance can differ with the order of rounding.
    const bool c_ok = sc == C_(ok), cxx_ok = scxx == obsynth::Status::ok;
#ifdef OBSYNTH_NEWTON
    const bool c_capped = sc == C_(not_converged);
    const bool cxx_capped = scxx == obsynth::Status::newton_not_converged;
#else
    const bool c_capped = false, cxx_capped = false;
#endif
    const bool same = c_ok == cxx_ok || sizeof(Scalar) == sizeof(float);
    if (!same || !(c_ok || c_capped) || !(cxx_ok || cxx_capped)) {
      expect(false, "step status", sc, static_cast<double>(scxx));
      return 1e300;
    }
    for (int i = 0; i < n; ++i) {
      const double a = static_cast<double>(c.xh[i]), b = static_cast<double>(cxx.estimate()(i));
      worst_agree = std::fmax(worst_agree, std::fabs(a - b) / std::fmax(1.0, std::fabs(b)));
      if (t >= 1.0) worst_track = std::fmax(worst_track, std::fabs(a - x[i]));
    }
  }
  expect(worst_agree <= agree_tol, "C and C++ steps agree", worst_agree, agree_tol);
  std::printf("epsilon %g: C vs C++ estimate %.3e (relative), tracking error after 1 s %.3e\n",
              epsilon, worst_agree, worst_track);
  return worst_track;
}

}  // namespace

int main() {
  const bool single = sizeof(Scalar) == sizeof(float);
#ifndef OBSYNTH_NEWTON
  reconstruct_from_exact_jets(single ? 1e-2 : 1e-9);
#endif
  // Both run the same filter in the same precision; only the order of rounding differs.
  const double agree = single ? 1e-3 : 1e-9;
  const double e1 = closed_loop(0.01, agree), e2 = closed_loop(0.005, agree);
  // The differentiators' bias shrinks with epsilon (differentiator.hpp: O(epsilon^(K+1-k))).
  expect(e1 < 0.15, "tracks the plant after 1 s (epsilon 0.01)", e1, 0.15);
  expect(e2 < 0.6 * e1, "halving epsilon reduces the tracking error", e2, 0.6 * e1);
  std::printf("%s perfect (C, %s): %d passed, %d failed\n", OBSYNTH_NAME,
              single ? "float" : "double", passed, failed);
  return failed == 0 ? 0 : 1;
}
