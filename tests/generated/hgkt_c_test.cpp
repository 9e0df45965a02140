// The C99 pair of a high-gain or Kalman-like theta observer against the C++ header of the same
// design (itself checked against GiNaC by hgkt_test.cpp): from the reference points, 50 steps
// of both with the same u, y; states must agree to rounding (the C solvers are hand-written,
// the C++ ones are Eigen's, so this also cross-checks the two factorisations).
#include <cmath>
#include <cstdio>
#include <string>

#include OBSYNTH_HGKT_HEADER
#include OBSYNTH_REFERENCE_HEADER
extern "C" {
#include OBSYNTH_C_HEADER
}

#define CAT2(a, b) a##b
#define CAT(a, b) CAT2(a, b)
#define C_(name) CAT(OBSYNTH_C_PREFIX, name)

int main() {
  using Scalar = C_(_scalar);
  using Obs = OBSYNTH_HGKT_CLASS<Scalar>;
  static_assert(Obs::nw == C_(_w), "observer state sizes differ");
  int failures = 0;
  const double rel = sizeof(Scalar) == sizeof(double) ? 1e-11 : 2e-4;
  for (int k = 0; k < ref::kPoints; ++k) {
    Obs cxx;
    C_(_observer) c;
    C_(_init)(&c);
    typename Obs::ObserverState w;
    for (int i = 0; i < Obs::nw; ++i) {
      w(i) = Scalar(ref::w[k][i]);
      c.w[i] = Scalar(ref::w[k][i]);
    }
    cxx.set_observer_state(w);
    Scalar u[Obs::m > 0 ? Obs::m : 1], y[1];
    typename Obs::Input ue;
    typename Obs::Output ye;
    for (int j = 0; j < Obs::m; ++j) ue(j) = u[j] = Scalar(ref::u[k][j]);
    ye(0) = y[0] = Scalar(ref::y[k][0]);
    for (int s = 0; s < 50; ++s) {
      const auto a = cxx.step(Scalar(1e-3), ue, ye);
      const auto b = C_(_step)(&c, Scalar(1e-3), u, y);
      // The two enums number their values differently: compare by name.
      const char* cxx_name = obsynth::status_name(a);
      const char* c_name = b == C_(_ok)           ? "ok"
                           : b == C_(_non_finite) ? "non_finite"
                           : b == C_(_singular)   ? "singular"
                                                  : "other";
      if (std::string(cxx_name) != c_name) {
        std::printf("FAIL point %d step %d: status %s (C++) vs %s (C)\n", k, s, cxx_name, c_name);
        ++failures;
        break;
      }
      if (a != obsynth::Status::ok) break;  // both refused the step (state kept): stop here
    }
    for (int i = 0; i < Obs::nw; ++i) {
      const double p = double(cxx.observer_state()(i)), q = double(c.w[i]);
      if (!(std::fabs(p - q) <= rel * std::fmax(1.0, std::fabs(p)))) {
        std::printf("FAIL point %d entry %d: C++ %.17g C %.17g\n", k, i, p, q);
        ++failures;
      }
    }
  }
  std::printf("%s: %d failures\n", OBSYNTH_C_HEADER, failures);
  return failures == 0 ? 0 : 1;
}
