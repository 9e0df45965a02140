// Tests of one generated C99 Riccati observer pair (--language c), compiled as C under the
// strict flags and driven from C++, in the pair's scalar type: numeric equivalence of
// riccati_rhs with GiNaC's dense evaluation (riccati_reference.cpp), reset packs Q0, the
// firmware step() in closed loop at every run-time parameter point with Q symmetric positive
// definite (our own LDL^T) after every step, and rejection of an indefinite Q (status singular,
// state kept).
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
constexpr int nw = C_(w);

#if OBSYNTH_HAS_PARAMS
#define PRM(p) &p,
using Params = C_(params);
#else
#define PRM(p)
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

Params params(int set) {
  Params q{};
#if OBSYNTH_HAS_PARAMS
  C_(params_init)(&q);
#endif
  ref::set_params(q, set);
  return q;
}

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

bool q_positive_definite(const Scalar* w) {
  double L[n][n] = {}, d[n] = {};
  for (int j = 0; j < n; ++j) {
    double s = static_cast<double>(w[packed(j, j)]);
    for (int k = 0; k < j; ++k) s -= L[j][k] * L[j][k] * d[k];
    if (!(s > 0) || !std::isfinite(s)) return false;
    d[j] = s;
    L[j][j] = 1;
    for (int i = j + 1; i < n; ++i) {
      double t = static_cast<double>(w[packed(i, j)]);
      for (int k = 0; k < j; ++k) t -= L[i][k] * L[j][k] * d[k];
      L[i][j] = t / d[j];
    }
  }
  return true;
}

const double kTol = sizeof(Scalar) == sizeof(double) ? 1e-12 : 2e-5;

void numeric_equivalence() {
  for (int k = 0; k < ref::kPoints; ++k) {
    [[maybe_unused]] const Params prm = params(k % ref::kParamSets);
    Scalar w[nw], dw[nw], u[m > 0 ? m : 1], y[p];
    for (int i = 0; i < n; ++i) w[i] = static_cast<Scalar>(ref::x[k][i]);
    for (int r = 0; r < n; ++r)
      for (int c = r; c < n; ++c) w[packed(r, c)] = static_cast<Scalar>(ref::Q[k][r * n + c]);
    for (int i = 0; i < m; ++i) u[i] = static_cast<Scalar>(ref::u[k][i]);
    for (int i = 0; i < p; ++i) y[i] = static_cast<Scalar>(ref::y[k][i]);
    C_(riccati_rhs)(w, u, y, PRM(prm) dw);
    double scale = 1;
    for (int i = 0; i < n; ++i) scale = std::fmax(scale, std::fabs(ref::dm[k][i]));
    for (int i = 0; i < n * n; ++i) scale = std::fmax(scale, std::fabs(ref::dQ[k][i]));
    for (int i = 0; i < n; ++i)
      expect(std::fabs(static_cast<double>(dw[i]) - ref::dm[k][i]) <= kTol * scale, "m'",
             static_cast<double>(dw[i]), ref::dm[k][i]);
    for (int r = 0; r < n; ++r)
      for (int c = r; c < n; ++c)
        expect(std::fabs(static_cast<double>(dw[packed(r, c)]) - ref::dQ[k][r * n + c]) <=
                   kTol * scale,
               "Q'", static_cast<double>(dw[packed(r, c)]), ref::dQ[k][r * n + c]);
  }
}

void closed_loop(int set) {
  C_(observer) o;
  C_(init)(&o);
  [[maybe_unused]] const Params prm = params(set);
#if OBSYNTH_HAS_PARAMS
  o.prm = prm;
#endif
  const double x0[n] = {OBSYNTH_X0}, xh0d[n] = {OBSYNTH_XH0};
  Scalar x[n], xh0[n];
  for (int i = 0; i < n; ++i)
    x[i] = static_cast<Scalar>(x0[i]), xh0[i] = static_cast<Scalar>(xh0d[i]);
  C_(reset)(&o, xh0);
  for (int r = 0; r < n; ++r)
    for (int c = r; c < n; ++c)
      expect(std::fabs(static_cast<double>(o.w[packed(r, c)]) - ref::Q0[0][r * n + c]) <= 1e-7,
             "reset: Q0 packed");
  const double dt = 1e-3;
  const long steps = static_cast<long>(OBSYNTH_T_END / dt + 0.5);
  auto field = [&](const Scalar* s, double t, Scalar* out) {
    Scalar u[m > 0 ? m : 1], tmp[n];
    for (int j = 0; j < m; ++j) u[j] = static_cast<Scalar>(0.5 * std::sin(t + j));
    C_(f)(s, PRM(prm) out);
    C_(g)(s, u, PRM(prm) tmp);
    for (int i = 0; i < n; ++i) out[i] += tmp[i];
  };
  long not_ok = 0, not_pd = 0;
  for (long k = 0; k < steps; ++k) {
    const double t = static_cast<double>(k) * dt;
    Scalar u[m > 0 ? m : 1], y[p];
    for (int j = 0; j < m; ++j) u[j] = static_cast<Scalar>(0.5 * std::sin(t + j));
    C_(h)(x, PRM(prm) y);
    not_ok += C_(step)(&o, static_cast<Scalar>(dt), u, y) != C_(ok);
    not_pd += !q_positive_definite(o.w);
    Scalar k1[n], k2[n], k3[n], k4[n], a[n];
    field(x, t, k1);
    for (int i = 0; i < n; ++i) a[i] = x[i] + static_cast<Scalar>(dt / 2) * k1[i];
    field(a, t + dt / 2, k2);
    for (int i = 0; i < n; ++i) a[i] = x[i] + static_cast<Scalar>(dt / 2) * k2[i];
    field(a, t + dt / 2, k3);
    for (int i = 0; i < n; ++i) a[i] = x[i] + static_cast<Scalar>(dt) * k3[i];
    field(a, t + dt, k4);
    for (int i = 0; i < n; ++i)
      x[i] += static_cast<Scalar>(dt / 6) * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i]);
  }
  expect(not_ok == 0, "every step returns ok", static_cast<double>(not_ok));
  expect(not_pd == 0, "Q symmetric positive definite after every step",
         static_cast<double>(not_pd));
  double err = 0;
  for (int i = 0; i < n; ++i) err = std::fmax(err, std::fabs(static_cast<double>(x[i] - o.xh[i])));
  const double tol = OBSYNTH_TOL * (sizeof(Scalar) == sizeof(double) ? 1 : 4);
  expect(err < tol, "closed loop error", err, tol);
  std::printf("closed loop (C, set %d): |x - xh|_inf = %.3g (tolerance %.3g)\n", set, err, tol);
}

void rejects_indefinite_q() {
  C_(observer) o;
  C_(init)(&o);
  for (int r = 0; r < n; ++r)
    for (int c = r; c < n; ++c) o.w[packed(r, c)] = r == c ? Scalar(-1) : Scalar(0);
  Scalar before[nw];
  for (int i = 0; i < nw; ++i) before[i] = o.w[i];
  Scalar u[m > 0 ? m : 1] = {}, y[p] = {};
  expect(C_(step)(&o, Scalar(1e-3), u, y) == C_(singular), "indefinite Q: step is singular");
  bool kept = true;
  for (int i = 0; i < nw; ++i) kept = kept && o.w[i] == before[i];
  expect(kept, "indefinite Q: state kept");
}

}  // namespace

int main() {
  numeric_equivalence();
  for (int set = 0; set < (OBSYNTH_HAS_PARAMS ? ref::kParamSets : 1); ++set) closed_loop(set);
  rejects_indefinite_q();
  std::printf("%d passed, %d failed\n", passed, failed);
  return failed == 0 ? 0 : 1;
}
