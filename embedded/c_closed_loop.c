/* SPDX-License-Identifier: MIT
 * Copyright (c) obsynth authors
 *
 * Closed-loop check of the GENERATED C99 canonical observer for slawinski17 (float pair from
 * `obsynth models/slawinski17.sym --language c --method canonical --precision float`), built
 * as C99 under the strict flags for the host and for a Cortex-M4F (embedded/run-qemu.sh).
 * Plant x' = f(x) + g(x, u) from the generated f and g, x(0) = (0.5, -0.3), u(t) = sin(t)
 * held over each step, one RK4 step per sample; observer from xh0 = (0, 0), dt = 1e-3, 5 s.
 * Checks: every step returns ok; at t = 5 s |x - xh|_inf <= 5e-3 (the C++ header's bound in
 * generated_closed_loop.cpp: poles -2, -2.5 and the O(dt) zero-order-hold floor).
 */
#include <math.h>
#include <stdio.h>

#include "slawinski17_canonical.h"

typedef slawinski17_canonical_scalar Scalar;
#define N slawinski17_canonical_n

static void plant_rhs(const Scalar* x, Scalar u, Scalar* dx) {
  Scalar a[N], b[N];
  int i;
  slawinski17_canonical_f(x, a);
  slawinski17_canonical_g(x, &u, b);
  for (i = 0; i < N; ++i) dx[i] = a[i] + b[i];
}

static void plant_step(Scalar* x, Scalar u, Scalar dt) {
  Scalar k1[N], k2[N], k3[N], k4[N], s[N];
  int i;
  plant_rhs(x, u, k1);
  for (i = 0; i < N; ++i) s[i] = x[i] + dt / 2.0f * k1[i];
  plant_rhs(s, u, k2);
  for (i = 0; i < N; ++i) s[i] = x[i] + dt / 2.0f * k2[i];
  plant_rhs(s, u, k3);
  for (i = 0; i < N; ++i) s[i] = x[i] + dt * k3[i];
  plant_rhs(s, u, k4);
  for (i = 0; i < N; ++i) x[i] += dt / 6.0f * (k1[i] + 2.0f * (k2[i] + k3[i]) + k4[i]);
}

int main(void) {
  slawinski17_canonical_observer obs;
  Scalar x[N] = {0.5f, -0.3f}, y;
  const Scalar dt = 1e-3f;
  int k, i, failures = 0;
  double err = 0.0;
  slawinski17_canonical_init(&obs);
  for (k = 0; k < 5000; ++k) {
    const Scalar u = sinf((Scalar)k * dt);
    slawinski17_canonical_h(x, &y);
    if (slawinski17_canonical_step(&obs, dt, &u, &y) != slawinski17_canonical_ok) ++failures;
    plant_step(x, u, dt);
    if (k % 500 == 499)
      printf("traj %.1f %.6f %.6f %.6f %.6f\n", (double)((Scalar)(k + 1) * dt), (double)x[0],
             (double)x[1], (double)obs.xh[0], (double)obs.xh[1]);
  }
  for (i = 0; i < N; ++i) err = fmax(err, fabs((double)x[i] - (double)obs.xh[i]));
  printf("final |x - xh| = %.3e (bound 5e-3), %d failed steps\n", err, failures);
  if (failures == 0 && err <= 5e-3) {
    printf("PASS\n");
    return 0;
  }
  printf("FAIL\n");
  return 1;
}
