// Hand-derived reference for the generated extended-linearization observers (independent of
// synth/designs/extended_linearization.cpp, the DAG and the printers): the model's field and
// the injection k(y) worked out in models/pendulum.sym's test (pendulum, closed form) and in
// the comments of models/cart_pendulum.sym (Taylor polynomial of order 6 of
// [3 asin y, 2 asin y + atanh y]: asin y = y + y^3/6 + 3 y^5/40 + O(y^7),
// atanh y = y + y^3/3 + y^5/5 + O(y^7)). Evaluated in long double.
#pragma once

#include <cmath>

namespace el_ref {

#if OBSYNTH_EL_MODEL == 1  // pendulum: f = [x2, -sin x1 - x2/4], g = [0, u], h = x1
inline long double h(const long double* x) {
  return x[0];
}
inline void field(const long double* x, long double u, long double* out) {
  out[0] = x[1];
  out[1] = -std::sin(x[0]) - x[1] / 4 + u;
}
inline void k(long double y, long double* out) {
  out[0] = 11.0L / 4 * y;
  out[1] = 21.0L / 16 * y - std::sin(y);
}
// Closed loop near the family x = (e, 0), u = sin e.
inline long double u_of_t(double t) {
  return std::sin(0.5L) + 0.2L * std::sin(static_cast<long double>(t));
}
constexpr double x0[2] = {0.5, 0}, xh0[2] = {0.8, -0.4};
constexpr double t_end = 15;
#else  // cart pendulum: f = [x2, sin x1], g = [0, -cos(x1) u], h = sin x1
inline long double h(const long double* x) {
  return std::sin(x[0]);
}
inline void field(const long double* x, long double u, long double* out) {
  out[0] = x[1];
  out[1] = std::sin(x[0]) - std::cos(x[0]) * u;
}
inline void k(long double y, long double* out) {
  const long double y3 = y * y * y, y5 = y3 * y * y;
  out[0] = 3 * y + y3 / 2 + 9 * y5 / 40;
  out[1] = 3 * y + 2 * y3 / 3 + 7 * y5 / 20;
}
// At the equilibrium x1 = asin(1/5), u = tan(x1) = 1/sqrt(24) (open loop unstable).
inline long double u_of_t(double) {
  return 1 / std::sqrt(24.0L);
}
constexpr double x0[2] = {0.20135792079033080, 0}, xh0[2] = {0.25135792079033080, -0.05};
constexpr double t_end = 10;
#endif

// xh' = f(xh) + g(xh, u) + k(y) - k(h(xh))
inline void rhs(const long double* xh, long double u, long double y, long double* out) {
  long double ky[2], kh[2];
  field(xh, u, out);
  k(y, ky);
  k(h(xh), kh);
  for (int i = 0; i < 2; ++i) out[i] += ky[i] - kh[i];
}

}  // namespace el_ref
