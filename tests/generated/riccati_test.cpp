// Tests of one generated Riccati observer header (C++), under the generated-code contract flags:
//  - numeric equivalence of riccati_rhs with GiNaC's dense evaluation (riccati_reference.cpp),
//    double and float, at every reference point and its parameter set;
//  - reset(): w = (xh0, Q0 packed upper triangle, row by row);
//  - closed loop with the firmware step (u, y held over dt) in double and float: every step ok,
//    Q symmetric positive definite (checked here by an LDL^T of our own) and finite after every
//    step, the error below the stated tolerance at the end, zero heap allocations while stepping;
//  - a state whose Q is not positive definite: step() returns Status::singular, state kept.
// Built per model with OBSYNTH_NS, OBSYNTH_CLASS, the headers and the closed-loop case
// (OBSYNTH_X0, OBSYNTH_XH0, OBSYNTH_T_END, OBSYNTH_TOL) given as macros.
#include <cmath>
#include <cstdio>

#include OBSYNTH_RICCATI_HEADER
#include OBSYNTH_REFERENCE_HEADER
#include "alloc_counter.hpp"

namespace gen = obsynth_gen::OBSYNTH_NS;

#if OBSYNTH_HAS_PARAMS
#define PRM(p) p,
#else
#define PRM(p)
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
using Obs = gen::OBSYNTH_CLASS<Scalar>;
template <class Scalar>
using F = gen::RiccatiFunctions<Scalar>;
constexpr int n = gen::n;
constexpr int nw = n + n * (n + 1) / 2;

#if OBSYNTH_HAS_PARAMS
template <class Scalar>
using Params = gen::ModelParams<Scalar>;
#else
template <class Scalar>
struct Params {};
#endif

template <class Scalar>
Params<Scalar> params(int set) {
  Params<Scalar> p;
  ref::set_params(p, set);
  return p;
}

// Position of Q(r, c), r <= c, in w: the packed upper triangle row by row after m.
int packed(int r, int c) {
  if (r > c) {
    const int t = r;
    r = c;
    c = t;
  }
  int k = n;
  for (int i = 0; i < r; ++i) k += n - i;
  return k + (c - r);
}

// Symmetric positive definite by LDL^T without pivoting (all pivots > 0, all finite).
template <class W>
bool q_positive_definite(const W& w) {
  double L[n][n] = {}, d[n] = {};
  for (int j = 0; j < n; ++j) {
    double s = static_cast<double>(w(packed(j, j)));
    for (int k = 0; k < j; ++k) s -= L[j][k] * L[j][k] * d[k];
    if (!(s > 0) || !std::isfinite(s)) return false;
    d[j] = s;
    L[j][j] = 1;
    for (int i = j + 1; i < n; ++i) {
      double t = static_cast<double>(w(packed(i, j)));
      for (int k = 0; k < j; ++k) t -= L[i][k] * L[j][k] * d[k];
      L[i][j] = t / d[j];
    }
  }
  return true;
}

template <class Scalar>
void numeric_equivalence(double tol) {
  for (int k = 0; k < ref::kPoints; ++k) {
    [[maybe_unused]] const Params<Scalar> prm = params<Scalar>(k % ref::kParamSets);
    typename Obs<Scalar>::ObserverState w, dw;
    typename Obs<Scalar>::Input u;
    typename Obs<Scalar>::Output y;
    for (int i = 0; i < n; ++i) w(i) = static_cast<Scalar>(ref::x[k][i]);
    for (int r = 0; r < n; ++r)
      for (int c = r; c < n; ++c) w(packed(r, c)) = static_cast<Scalar>(ref::Q[k][r * n + c]);
    for (int i = 0; i < gen::m; ++i) u(i) = static_cast<Scalar>(ref::u[k][i]);
    for (int i = 0; i < gen::p; ++i) y(i) = static_cast<Scalar>(ref::y[k][i]);
    F<Scalar>::riccati_rhs(w, u, y, PRM(prm) dw);
    double scale = 1;
    for (int i = 0; i < n; ++i) scale = std::fmax(scale, std::fabs(ref::dm[k][i]));
    for (int i = 0; i < n * n; ++i) scale = std::fmax(scale, std::fabs(ref::dQ[k][i]));
    for (int i = 0; i < n; ++i)
      expect(std::fabs(static_cast<double>(dw(i)) - ref::dm[k][i]) <= tol * scale, "m'",
             static_cast<double>(dw(i)), ref::dm[k][i]);
    for (int r = 0; r < n; ++r)
      for (int c = r; c < n; ++c)
        expect(
            std::fabs(static_cast<double>(dw(packed(r, c))) - ref::dQ[k][r * n + c]) <= tol * scale,
            "Q'", static_cast<double>(dw(packed(r, c))), ref::dQ[k][r * n + c]);
  }
}

template <class Scalar>
void reset_packs_q0() {
  Obs<Scalar> obs;
  typename Obs<Scalar>::State xh0;
  for (int i = 0; i < n; ++i) xh0(i) = static_cast<Scalar>(0.25 * (i + 1));
  obs.reset(xh0);
  const auto& w = obs.observer_state();
  for (int i = 0; i < n; ++i) expect(w(i) == xh0(i), "reset: m = xh0");
  for (int r = 0; r < n; ++r)
    for (int c = r; c < n; ++c)
      expect(std::fabs(static_cast<double>(w(packed(r, c))) - ref::Q0[0][r * n + c]) <= 1e-7,
             "reset: Q0 packed", static_cast<double>(w(packed(r, c))), ref::Q0[0][r * n + c]);
  static_assert(Obs<Scalar>::nw == nw, "observer state size n + n(n+1)/2");
}

template <class Scalar>
void closed_loop(double tol, const char* what, int set) {
  using O = Obs<Scalar>;
  O obs;
  [[maybe_unused]] const Params<Scalar> prm = params<Scalar>(set);
#if OBSYNTH_HAS_PARAMS
  obs.set_params(prm);
#endif
  const double x0[n] = {OBSYNTH_X0}, xh0[n] = {OBSYNTH_XH0};
  typename O::State x, xh, k1, k2, k3, k4, a, tmp;
  for (int i = 0; i < n; ++i)
    x(i) = static_cast<Scalar>(x0[i]), xh(i) = static_cast<Scalar>(xh0[i]);
  obs.reset(xh);
  const double dt = 1e-3;
  const long steps = static_cast<long>(OBSYNTH_T_END / dt + 0.5);
  auto field = [&](const typename O::State& s, double t, typename O::State& out) {
    typename O::Input u;
    for (int j = 0; j < gen::m; ++j) u(j) = static_cast<Scalar>(0.5 * std::sin(t + j));
    F<Scalar>::f(s, PRM(prm) out);
    F<Scalar>::g(s, u, PRM(prm) tmp);
    out += tmp;
  };
  long not_ok = 0, not_pd = 0;
  obsynth::test::AllocationCounter counter;
  for (long k = 0; k < steps; ++k) {
    const double t = static_cast<double>(k) * dt;
    typename O::Input u;
    for (int j = 0; j < gen::m; ++j) u(j) = static_cast<Scalar>(0.5 * std::sin(t + j));
    typename O::Output y;
    F<Scalar>::h(x, PRM(prm) y);
    not_ok += obs.step(static_cast<Scalar>(dt), u, y) != obsynth::Status::ok;
    not_pd += !q_positive_definite(obs.observer_state());
    field(x, t, k1);
    a = x + static_cast<Scalar>(dt / 2) * k1;
    field(a, t + dt / 2, k2);
    a = x + static_cast<Scalar>(dt / 2) * k2;
    field(a, t + dt / 2, k3);
    a = x + static_cast<Scalar>(dt) * k3;
    field(a, t + dt, k4);
    x += static_cast<Scalar>(dt / 6) * (k1 + Scalar(2) * k2 + Scalar(2) * k3 + k4);
  }
  const std::size_t allocations = counter.allocations();
  expect(allocations == 0, "no heap allocation while stepping", static_cast<double>(allocations));
  expect(not_ok == 0, "every step returns Status::ok", static_cast<double>(not_ok));
  expect(not_pd == 0, "Q symmetric positive definite after every step",
         static_cast<double>(not_pd));
  double err = 0;
  for (int i = 0; i < n; ++i)
    err = std::fmax(err, std::fabs(static_cast<double>(x(i) - obs.estimate()(i))));
  expect(err < tol, what, err, tol);
  std::printf("%s: |x - xh|_inf = %.3g at t = %g (tolerance %.3g)\n", what, err,
              static_cast<double>(OBSYNTH_T_END), tol);
}

template <class Scalar>
void rejects_indefinite_q() {
  using O = Obs<Scalar>;
  O obs;
  typename O::ObserverState w = obs.observer_state();
  for (int r = 0; r < n; ++r)
    for (int c = r; c < n; ++c) w(packed(r, c)) = r == c ? Scalar(-1) : Scalar(0);
  obs.set_observer_state(w);
  typename O::Input u = O::Input::Zero();
  typename O::Output y = O::Output::Zero();
  const obsynth::Status s = obs.step(Scalar(1e-3), u, y);
  expect(s == obsynth::Status::singular, "indefinite Q: step returns singular");
  bool kept = true;
  for (int i = 0; i < nw; ++i) kept = kept && obs.observer_state()(i) == w(i);
  expect(kept, "indefinite Q: state kept");
}

}  // namespace

int main() {
  numeric_equivalence<double>(1e-12);
  numeric_equivalence<float>(2e-5);
  reset_packs_q0<double>();
  reset_packs_q0<float>();
  for (int set = 0; set < (OBSYNTH_HAS_PARAMS ? ref::kParamSets : 1); ++set) {
    closed_loop<double>(OBSYNTH_TOL, "closed loop (double)", set);
    closed_loop<float>(OBSYNTH_TOL * 4, "closed loop (float)", set);
  }
  rejects_indefinite_q<double>();
  rejects_indefinite_q<float>();
  std::printf("%d passed, %d failed\n", passed, failed);
  return failed == 0 ? 0 : 1;
}
