/* SPDX-License-Identifier: MIT
 * Copyright (c) obsynth authors
 *
 * The numeric kernels of an observer step, once, in C99: the C back end's generated sources
 * include them, and obsynth's simulator compiles the same text as C++ (double), so that the
 * simulated step and the firmware step are one implementation.
 *
 * Include after `typedef float Scalar;` or `typedef double Scalar;`, with OBSYNTH_C_FLOAT
 * defined to 1 for float (fabsf, sqrtf, FLT_EPSILON). All functions are `static inline`:
 * private to the including file, no link-time names, no warning when one is unused. Matrices
 * are row-major arrays; no heap; failure is a 0 return.
 *
 * From C++ (the simulator): include <cmath> first, then this header inside a namespace that
 * declares Scalar.
 */
/* One inclusion per precision (a C++ file may include it for double and for float, each in a
 * namespace of its own). */
#if defined(OBSYNTH_C_FLOAT) && OBSYNTH_C_FLOAT
#ifndef OBSYNTH_C_KERNELS_FLOAT_H
#define OBSYNTH_C_KERNELS_FLOAT_H
#define OBSYNTH_C_KERNELS_BODY
#endif
#else
#ifndef OBSYNTH_C_KERNELS_DOUBLE_H
#define OBSYNTH_C_KERNELS_DOUBLE_H
#define OBSYNTH_C_KERNELS_BODY
#endif
#endif

#ifdef OBSYNTH_C_KERNELS_BODY
#undef OBSYNTH_C_KERNELS_BODY

#undef OBSYNTH_C_ISFINITE
#undef OBSYNTH_C_FABS
#undef OBSYNTH_C_SQRT
#undef OBSYNTH_C_EXP
#undef OBSYNTH_C_FLOOR
#undef OBSYNTH_C_UNROLL
#undef OBSYNTH_C_SQRT_EPSILON
#ifdef __cplusplus
#define OBSYNTH_C_ISFINITE(x) std::isfinite(x)
#define OBSYNTH_C_FABS(x) std::fabs(x)
#define OBSYNTH_C_SQRT(x) std::sqrt(x)
#define OBSYNTH_C_EXP(x) std::exp(x)
#define OBSYNTH_C_FLOOR(x) std::floor(x)
/* The C++ runtime calls the kernels with compile-time sizes: unrolled completely, the RK4 stage
 * vectors stay in registers (un-unrolled, the Riccati step of seed 003 took 1.5x as long). The C
 * back end keeps the loops (code size at -Os on a microcontroller). */
#if defined(__GNUC__) && !defined(__clang__)
#define OBSYNTH_C_UNROLL _Pragma("GCC unroll 16")
#elif defined(__clang__)
#define OBSYNTH_C_UNROLL _Pragma("unroll 16")
#else
#define OBSYNTH_C_UNROLL
#endif
#else
#include <math.h>
#define OBSYNTH_C_ISFINITE(x) isfinite(x)
#if defined(OBSYNTH_C_FLOAT) && OBSYNTH_C_FLOAT
#define OBSYNTH_C_FABS(x) fabsf(x)
#define OBSYNTH_C_SQRT(x) sqrtf(x)
#define OBSYNTH_C_EXP(x) expf(x)
#define OBSYNTH_C_FLOOR(x) floorf(x)
#else
#define OBSYNTH_C_FABS(x) fabs(x)
#define OBSYNTH_C_SQRT(x) sqrt(x)
#define OBSYNTH_C_EXP(x) exp(x)
#define OBSYNTH_C_FLOOR(x) floor(x)
#endif
#define OBSYNTH_C_UNROLL
#endif

/* sqrt(epsilon) of the precision (obsynth's lu_conditioning_limit). */
#if defined(OBSYNTH_C_FLOAT) && OBSYNTH_C_FLOAT
#define OBSYNTH_C_SQRT_EPSILON 3.4526698e-4f
#else
#define OBSYNTH_C_SQRT_EPSILON 1.4901161193847656e-8
#endif

/* 1 when every one of the k values is finite. */
static inline int obsynth_all_finite(const Scalar* v, int k) {
  int i;
  for (i = 0; i < k; ++i)
    if (!OBSYNTH_C_ISFINITE(v[i])) return 0;
  return 1;
}

/* Exact zero-order-hold discretisation of w' = A w + c (A: n x n): E = e^{A dt} - I and
 * Gamma = int_0^dt e^{A s} ds, by scaling and squaring of their Taylor series on h = dt / 2^s
 * with ||A h||_1 <= 1/2 (terms summed until they no longer change the sums), then s doublings
 * E(2h) = E(h) (E(h) + 2 I), Gamma(2h) = Gamma(h) + (E(h) + I) Gamma(h) (the C++ runtime's
 * discretise_linear). E, not Phi: in float Phi's entries round to 1 + O(eps), E keeps the
 * small terms' relative precision; the step adds the increment E w + Gamma c to w.
 * work: 4 n^2 Scalars. 0 for a bad dt or a non-finite result. */
static inline int obsynth_discretise(const Scalar* A, int n, Scalar dt, Scalar* E, Scalar* G,
                                     Scalar* work) {
  Scalar* Ah = work;
  Scalar* term = work + n * n;
  Scalar* tmp = work + 2 * n * n;
  Scalar* E2 = work + 3 * n * n;
  Scalar norm = (Scalar)0, h = dt;
  int i, j, k, s, squarings = 0;
  if (!OBSYNTH_C_ISFINITE(dt) || !(dt > (Scalar)0) || !obsynth_all_finite(A, n * n)) return 0;
  for (j = 0; j < n; ++j) {
    Scalar col = (Scalar)0;
    for (i = 0; i < n; ++i) col += OBSYNTH_C_FABS(A[i * n + j]);
    norm = col > norm ? col : norm;
  }
  norm *= dt;
  while (norm > (Scalar)0.5 && squarings < 64) {
    norm *= (Scalar)0.5;
    h *= (Scalar)0.5;
    ++squarings;
  }
  for (i = 0; i < n * n; ++i) {
    Ah[i] = A[i] * h;
    term[i] = Ah[i];
    E[i] = Ah[i];
    G[i] = Ah[i] * (h / (Scalar)2) + (i % (n + 1) == 0 ? h : (Scalar)0);
  }
  for (k = 2; k <= 30; ++k) {
    int changed = 0;
    for (i = 0; i < n; ++i)
      for (j = 0; j < n; ++j) {
        Scalar acc = (Scalar)0;
        for (s = 0; s < n; ++s) acc += term[i * n + s] * Ah[s * n + j];
        tmp[i * n + j] = acc / (Scalar)k;
      }
    for (i = 0; i < n * n; ++i) {
      const Scalar e = E[i] + tmp[i];
      const Scalar g = G[i] + tmp[i] * (h / (Scalar)(k + 1));
      if (e != E[i] || g != G[i]) changed = 1;
      term[i] = tmp[i];
      E[i] = e;
      G[i] = g;
    }
    if (!changed) break;
  }
  /* Doublings; tmp holds the new Gamma, E2 the new E. */
  for (k = 0; k < squarings; ++k) {
    for (i = 0; i < n; ++i)
      for (j = 0; j < n; ++j) {
        Scalar eg = (Scalar)0, ee = (Scalar)0;
        for (s = 0; s < n; ++s) {
          eg += E[i * n + s] * G[s * n + j];
          ee += E[i * n + s] * E[s * n + j];
        }
        tmp[i * n + j] = G[i * n + j] + G[i * n + j] + eg;
        E2[i * n + j] = ee + E[i * n + j] + E[i * n + j];
      }
    for (i = 0; i < n * n; ++i) {
      E[i] = E2[i];
      G[i] = tmp[i];
    }
  }
  return obsynth_all_finite(E, n * n) && obsynth_all_finite(G, n * n);
}

/* Classical RK4 for w' = F(w), one stage at a time, so that each caller evaluates F its own
 * way (generated C functions, C++ callables, the simulator's expression DAG) around one scheme:
 *
 *   F(w0) -> k;  obsynth_rk4_stage(0, h, n, w0, k, acc, t);
 *   F(t)  -> k;  obsynth_rk4_stage(1, h, n, w0, k, acc, t);
 *   F(t)  -> k;  obsynth_rk4_stage(2, h, n, w0, k, acc, t);
 *   F(t)  -> k;  obsynth_rk4_stage(3, h, n, w0, k, acc, w1);   w1: the new state
 *
 * acc gathers k1 + 2 k2 + 2 k3 and t is the next stage point (w0 + h/2 k1, w0 + h/2 k2,
 * w0 + h k3); the last stage writes w1 = w0 + h/6 (acc + k4), which may be w0 itself. */
static inline void obsynth_rk4_stage(int stage, Scalar h, int n, const Scalar* w0, const Scalar* k,
                                     Scalar* acc, Scalar* t) {
  const Scalar half = h * (Scalar)0.5, sixth = h / (Scalar)6;
  int i;
  OBSYNTH_C_UNROLL for (i = 0; i < n; ++i) switch (stage) {
    case 0:
      acc[i] = k[i];
      t[i] = w0[i] + half * k[i];
      break;
    case 1:
      acc[i] += (Scalar)2 * k[i];
      t[i] = w0[i] + half * k[i];
      break;
    case 2:
      acc[i] += (Scalar)2 * k[i];
      t[i] = w0[i] + h * k[i];
      break;
    default:
      t[i] = w0[i] + sixth * (acc[i] + k[i]);
  }
}

/* The number of equal sub-steps of dt no longer than max_h: ceil(dt / max_h) in 1..4096 (1 for
 * max_h <= 0 or a ratio that is not a number). */
static inline int obsynth_substeps(Scalar dt, Scalar max_h) {
  const Scalar ratio = max_h > (Scalar)0 ? dt / max_h : (Scalar)0;
  if (!(ratio > (Scalar)1)) return 1;
  if (ratio >= (Scalar)4096) return 4096;
  return (int)ratio + ((Scalar)(int)ratio < ratio ? 1 : 0);
}

/* One exact zero-order-hold step with obsynth_discretise's matrices: w1 = w0 + (E w0 + G c)
 * (increment = 1, E = Phi - I: the increment is added to w0 once, keeping its relative
 * precision), or w1 = E w0 + G c (increment = 0, E = Phi: double precision, where Phi's rounding
 * is negligible). G is n x k (Gamma, k = n, or Gamma B for k held inputs). Per row, G c is summed
 * first and E's columns are added to it by multiply-adds, so w0 enters the step-to-step
 * dependency chain through one multiply-add per column rather than through a product that is
 * summed and then added to G c (seed 003's step: 0.90 of the expert's time instead of 1.0).
 * k >= 1; w1 must not alias w0. */
static inline void obsynth_exact_step(const Scalar* E, const Scalar* G, const Scalar* w0,
                                      const Scalar* c, int n, int k, int increment, Scalar* w1) {
  int i, j;
  for (i = 0; i < n; ++i) {
    Scalar acc = G[i * k] * c[0];
    for (j = 1; j < k; ++j) acc += G[i * k + j] * c[j];
    for (j = 0; j < n; ++j) acc += E[i * n + j] * w0[j];
    w1[i] = increment ? w0[i] + acc : acc;
  }
}

/* The symmetric d x d matrix stored as its upper triangle, row by row, at w + off. */
static inline void obsynth_unpack_symmetric(const Scalar* w, int off, int d, Scalar* M) {
  int r, c, k = off;
  for (r = 0; r < d; ++r)
    for (c = r; c < d; ++c, ++k) M[r * d + c] = M[c * d + r] = w[k];
}

/* M = L L^T in place (lower triangle); 0 when M is not positive definite. */
static inline int obsynth_cholesky(Scalar* M, int d) {
  int i, j, k;
  for (j = 0; j < d; ++j) {
    Scalar s = M[j * d + j];
    for (k = 0; k < j; ++k) s -= M[j * d + k] * M[j * d + k];
    if (!(s > (Scalar)0) || !OBSYNTH_C_ISFINITE(s)) return 0;
    M[j * d + j] = OBSYNTH_C_SQRT(s);
    for (i = j + 1; i < d; ++i) {
      Scalar t = M[i * d + j];
      for (k = 0; k < j; ++k) t -= M[i * d + k] * M[j * d + k];
      M[i * d + j] = t / M[j * d + j];
    }
  }
  return 1;
}

/* x = M^-1 v for symmetric positive definite M (Cholesky, M overwritten); 0 when M is not
 * positive definite or x is not finite. */
static inline int obsynth_solve_cholesky(Scalar* M, int d, const Scalar* v, Scalar* x) {
  int i, k;
  if (!obsynth_cholesky(M, d)) return 0;
  for (i = 0; i < d; ++i) {
    Scalar t = v[i];
    for (k = 0; k < i; ++k) t -= M[i * d + k] * x[k];
    x[i] = t / M[i * d + i];
  }
  for (i = d - 1; i >= 0; --i) {
    Scalar t = x[i];
    for (k = i + 1; k < d; ++k) t -= M[k * d + i] * x[k];
    x[i] = t / M[i * d + i];
  }
  return obsynth_all_finite(x, d);
}

/* x = M^-1 v by LU with partial pivoting (M overwritten); 0 when a pivot is at most
 * sqrt(epsilon) times the largest one (condition number >= epsilon^-1/2: half the digits of
 * M^-1 v lost; obsynth's lu_conditioning_limit), or when x is not finite. */
static inline int obsynth_solve_lu(Scalar* M, int d, const Scalar* v, Scalar* x) {
  int i, j, k;
  Scalar largest = (Scalar)0, smallest = (Scalar)0;
  for (i = 0; i < d; ++i) x[i] = v[i];
  for (k = 0; k < d; ++k) {
    int p = k;
    for (i = k + 1; i < d; ++i)
      if (OBSYNTH_C_FABS(M[i * d + k]) > OBSYNTH_C_FABS(M[p * d + k])) p = i;
    if (p != k) {
      for (j = 0; j < d; ++j) {
        const Scalar t = M[k * d + j];
        M[k * d + j] = M[p * d + j];
        M[p * d + j] = t;
      }
      {
        const Scalar t = x[k];
        x[k] = x[p];
        x[p] = t;
      }
    }
    {
      const Scalar a = OBSYNTH_C_FABS(M[k * d + k]);
      if (!(a > (Scalar)0)) return 0; /* zero or NaN pivot */
      if (a > largest) largest = a;
      if (k == 0 || a < smallest) smallest = a;
    }
    for (i = k + 1; i < d; ++i) {
      const Scalar f = M[i * d + k] / M[k * d + k];
      for (j = k; j < d; ++j) M[i * d + j] -= f * M[k * d + j];
      x[i] -= f * x[k];
    }
  }
  if (!OBSYNTH_C_ISFINITE(largest) || !(smallest > OBSYNTH_C_SQRT_EPSILON * largest)) return 0;
  for (i = d - 1; i >= 0; --i) {
    Scalar t = x[i];
    for (k = i + 1; k < d; ++k) t -= M[i * d + k] * x[k];
    x[i] = t / M[i * d + i];
  }
  return obsynth_all_finite(x, d);
}

/* 1 when the symmetric d x d block packed at w + off (upper triangle, row by row) is positive
 * definite: every pivot of its square-root-free Cholesky factorisation L D L^T is finite and
 * > 0 (exactly when L L^T exists). work: d * d + d Scalars. */
static inline int obsynth_packed_positive_definite(const Scalar* w, int off, int d, Scalar* work) {
  Scalar* L = work;
  Scalar* D = work + d * d;
  int i, j, k;
  for (j = 0; j < d; ++j) {
    const int row = off + j * d - j * (j - 1) / 2; /* (j, j) */
    Scalar s = w[row];
    for (k = 0; k < j; ++k) s -= L[j * d + k] * L[j * d + k] * D[k];
    if (!(s > (Scalar)0) || !OBSYNTH_C_ISFINITE(s)) return 0;
    D[j] = s;
    {
      const Scalar inv = (Scalar)1 / s; /* one division per column */
      for (i = j + 1; i < d; ++i) {
        Scalar t = w[row + (i - j)];
        for (k = 0; k < j; ++k) t -= L[i * d + k] * L[j * d + k] * D[k];
        L[i * d + j] = t * inv;
      }
    }
  }
  return 1;
}

/* ---- the jet differentiator (obsynth::JetDifferentiator; seed 003's perfect observer) ----
 * A linear differentiator of order K with a (K+1)-fold pole at -1/epsilon, in scaled
 * coordinates eta_i = epsilon^i y^(i), exact for a sample path linear between samples. */

/* binomial(n, k) as a Scalar (small arguments: exact). */
static inline Scalar obsynth_binomial(int n, int k) {
  Scalar r = (Scalar)1;
  int i;
  for (i = 1; i <= k; ++i) r = r * (Scalar)(n - k + i) / (Scalar)i;
  return r;
}

/* Phi(h) = e^{-h} sum_{j=0..K} (h N)^j / j! with N = M + I nilpotent (exact, no truncation),
 * row-major (K+1) x (K+1); Horner: P = I + (h/j) N P, j = K..1. work: 3 (K+1)^2 Scalars. */
static inline void obsynth_jet_transition(Scalar* phi, int K, Scalar h, Scalar* work) {
  const int d = K + 1;
  Scalar* Nm = work;
  Scalar* Pm = work + d * d;
  Scalar* Tm = work + 2 * d * d;
  Scalar e;
  int i, j, k, s;
  if (h > (Scalar)200) { /* e^{-h} h^K / K! has underflowed: avoid 0 * Inf */
    for (i = 0; i < d * d; ++i) phi[i] = (Scalar)0;
    return;
  }
  for (i = 0; i < d * d; ++i) {
    Nm[i] = (Scalar)0;
    Pm[i] = i % (d + 1) == 0 ? (Scalar)1 : (Scalar)0;
  }
  for (i = 0; i < d; ++i) {
    if (i < K) Nm[i * d + i + 1] = (Scalar)1;
    Nm[i * d] -= obsynth_binomial(K + 1, i + 1);
    Nm[i * d + i] += (Scalar)1;
  }
  for (j = K; j >= 1; --j) {
    for (i = 0; i < d; ++i)
      for (k = 0; k < d; ++k) {
        Scalar acc = (Scalar)0;
        for (s = 0; s < d; ++s) acc += Nm[i * d + s] * Pm[s * d + k];
        Tm[i * d + k] = acc;
      }
    for (i = 0; i < d * d; ++i)
      Pm[i] = (i % (d + 1) == 0 ? (Scalar)1 : (Scalar)0) + (h / (Scalar)j) * Tm[i];
  }
  e = OBSYNTH_C_EXP(-h);
  for (i = 0; i < d * d; ++i) phi[i] = e * Pm[i];
}

/* Starts a differentiator at (y0, 0, ..., 0). */
static inline void obsynth_jet_reset(Scalar* eta, Scalar* y_prev, int K, Scalar y0) {
  int i;
  for (i = 0; i <= K; ++i) eta[i] = (Scalar)0;
  eta[0] = y0;
  *y_prev = y0;
}

/* Advances a differentiator by dt to the sample y (phi and cached_dt: its transition matrix,
 * row-major, and the dt it is for, recomputed when dt changes); 0 (state kept) if dt or y is
 * invalid or the result is not finite. work: 3 (K+1)^2 + 2 (K+1) Scalars. */
static inline int obsynth_jet_update(Scalar* eta, Scalar* phi, Scalar* cached_dt, Scalar* y_prev,
                                     int K, Scalar epsilon, Scalar dt, Scalar y, Scalar* work) {
  const int d = K + 1;
  Scalar* dv = work + 3 * d * d;
  Scalar* next = dv + d;
  Scalar slope;
  int i, k;
  if (!OBSYNTH_C_ISFINITE(dt) || !OBSYNTH_C_ISFINITE(y) || !(dt > (Scalar)0)) return 0;
  if (K == 0) {
    eta[0] = y;
    *y_prev = y;
    return 1;
  }
  if (dt < *cached_dt || dt > *cached_dt) { /* exact cache key, recomputed when dt changes */
    obsynth_jet_transition(phi, K, dt / epsilon, work);
    *cached_dt = dt;
  }
  slope = epsilon * ((y - *y_prev) / dt);
  for (i = 0; i < d; ++i) dv[i] = eta[i];
  dv[0] -= *y_prev;
  dv[1] -= slope;
  for (i = 0; i < d; ++i) {
    Scalar acc = (Scalar)0;
    for (k = 0; k < d; ++k) acc += phi[i * d + k] * dv[k];
    next[i] = acc;
  }
  next[0] += y;
  next[1] += slope;
  if (!obsynth_all_finite(next, d)) return 0;
  for (i = 0; i < d; ++i) eta[i] = next[i];
  *y_prev = y;
  return 1;
}

/* Unscales eta_i = epsilon^i y^(i) into the jet (y, y', ..., y^(K)), stored with a stride. */
static inline void obsynth_jet_read(const Scalar* eta, int K, Scalar epsilon, Scalar* out,
                                    int stride) {
  Scalar scale = (Scalar)1;
  int i;
  for (i = 0; i <= K; ++i) {
    out[i * stride] = eta[i] / scale;
    scale *= epsilon;
  }
}

/* Newton on map(x) = z with the inverse Jacobian tau(x) = (d map / dx)^-1 given (column-major),
 * by reverse communication: the kernel holds the iteration (stopping rule, iteration limit,
 * fallback) and the caller evaluates map and tau where it asks, so that C, C++ and the
 * simulator run one loop with their own function calls:
 *
 *   obsynth_newton_begin(&nw, z, x, n, iterations, tol);    x: the seed (previous estimate)
 *   for (;;) {
 *     map(x, Tx);
 *     if (!obsynth_newton_residual(&nw, Tx, z, n, r, x, x_prev)) break;   nw.status: verdict
 *     tau(x, tau);
 *     obsynth_newton_step(tau, r, n, dx);
 *     obsynth_newton_apply(&nw, dx, n, x, x_prev);
 *   }
 *
 * Stopping rule |r|_inf <= tol (1 + |z|_inf) with r = map(x) - z (absolute for |z| <~ 1,
 * relative beyond), tested at every iterate including the seed. Verdicts: converged; not
 * converged after `iterations` updates (x: the last iterate); non-finite residual (x: the last
 * iterate whose residual was finite, the seed if it was the first). */
enum {
  OBSYNTH_NEWTON_RUNNING = 0,
  OBSYNTH_NEWTON_CONVERGED = 1,
  OBSYNTH_NEWTON_NOT_CONVERGED = 2,
  OBSYNTH_NEWTON_NON_FINITE = 3
};
typedef struct {
  Scalar threshold;     /* tol (1 + |z|_inf) */
  Scalar residual_norm; /* |r|_inf at the last iterate tested */
  int iterations;       /* updates allowed */
  int updates;          /* updates made */
  int status;           /* OBSYNTH_NEWTON_* */
} obsynth_newton;

/* A non-finite seed x, z or tol ends the iteration before it starts (status non-finite). */
static inline void obsynth_newton_begin(obsynth_newton* s, const Scalar* z, const Scalar* x, int n,
                                        int iterations, Scalar tol) {
  Scalar z_norm = (Scalar)0;
  int i;
  for (i = 0; i < n; ++i) z_norm = OBSYNTH_C_FABS(z[i]) > z_norm ? OBSYNTH_C_FABS(z[i]) : z_norm;
  s->threshold = tol * ((Scalar)1 + z_norm);
  s->residual_norm = (Scalar)0;
  s->iterations = iterations;
  s->updates = 0;
  s->status = OBSYNTH_C_ISFINITE(s->threshold) && obsynth_all_finite(x, n)
                  ? OBSYNTH_NEWTON_RUNNING
                  : OBSYNTH_NEWTON_NON_FINITE;
}

/* r = Tx - z at the current x (Tx = map(x)); 1 when the caller must supply tau(x) for another
 * update, 0 when the iteration has ended (s->status). A non-finite residual ends it with x back
 * at the previous iterate. */
static inline int obsynth_newton_residual(obsynth_newton* s, const Scalar* Tx, const Scalar* z,
                                          int n, Scalar* r, Scalar* x, const Scalar* x_prev) {
  Scalar norm = (Scalar)0;
  int i, finite = 1;
  if (s->status != OBSYNTH_NEWTON_RUNNING) return 0;
  for (i = 0; i < n; ++i) {
    r[i] = Tx[i] - z[i];
    finite = finite && OBSYNTH_C_ISFINITE(r[i]);
    norm = OBSYNTH_C_FABS(r[i]) > norm ? OBSYNTH_C_FABS(r[i]) : norm;
  }
  if (!finite) {
    if (s->updates > 0)
      for (i = 0; i < n; ++i) x[i] = x_prev[i];
    s->status = OBSYNTH_NEWTON_NON_FINITE;
    return 0;
  }
  s->residual_norm = norm;
  if (norm <= s->threshold) {
    s->status = OBSYNTH_NEWTON_CONVERGED;
    return 0;
  }
  if (s->updates >= s->iterations) {
    s->status = OBSYNTH_NEWTON_NOT_CONVERGED;
    return 0;
  }
  return 1;
}

/* The Newton update dx = tau r, with tau = (d map / dx)^-1 at x, column-major. */
static inline void obsynth_newton_step(const Scalar* tau, const Scalar* r, int n, Scalar* dx) {
  int i, j;
  for (i = 0; i < n; ++i) {
    dx[i] = (Scalar)0;
    for (j = 0; j < n; ++j) dx[i] += tau[j * n + i] * r[j];
  }
}

/* x <- x - dx (x_prev keeps x for the fallback). */
static inline void obsynth_newton_apply(obsynth_newton* s, const Scalar* dx, int n, Scalar* x,
                                        Scalar* x_prev) {
  int i;
  for (i = 0; i < n; ++i) {
    x_prev[i] = x[i];
    x[i] -= dx[i];
  }
  ++s->updates;
}

/* ---- The finite-time observer's delay line and table estimate (seed 004: SampledDelay) ---- */

/* One sample into the delay line of D + 1 slots of `filters` values each: the next slot gets
 * decay .* z_head + gain .* y (filter j reads output j % outputs) and u_ring the input u_now.
 * 1 once D samples have passed since the reset (the estimate can be formed). */
static inline int obsynth_delay_push(Scalar* ring, Scalar* u_ring, int* head, int* filled, int D,
                                     int filters, const Scalar* decay, const Scalar* gain,
                                     const Scalar* y, int outputs, Scalar u_now) {
  const int next = *head == D ? 0 : *head + 1;
  int j;
  for (j = 0; j < filters; ++j)
    ring[next * filters + j] = decay[j] * ring[*head * filters + j] + gain[j] * y[j % outputs];
  u_ring[next] = u_now;
  *head = next;
  if (*filled < D) ++*filled;
  return *filled >= D;
}

/* The input level of this step (the tables are indexed by a level of the input u): v = u_now,
 * or with window_mean the mean of the last D samples of u_ring (and then, with slope != 0, in
 * *slope the least-squares slope of those samples per unit time, sample a = 0 the newest).
 * Nearest or lower level of (v - lo) / step, clamped to 0..levels - 1; with interpolate the
 * lower of two neighbouring levels and the fraction *frac towards the upper one. */
static inline void obsynth_delay_level(const Scalar* u_ring, int head, int D, Scalar u_now,
                                       int window_mean, Scalar* slope, Scalar dt, Scalar lo,
                                       Scalar step, int levels, int nearest, int interpolate,
                                       int* level, Scalar* frac) {
  Scalar v = u_now;
  int k;
  if (window_mean) {
    const int old = head == D ? 0 : head + 1; /* D samples ago: not in the window */
    Scalar acc = (Scalar)0;
    for (k = 0; k <= D; ++k)
      if (k != old) acc += u_ring[k];
    v = acc / (Scalar)D;
    if (slope) {
      Scalar sxy = (Scalar)0, sxx = (Scalar)0;
      for (k = 0; k < D; ++k) {
        const Scalar da = (Scalar)k - (Scalar)(D - 1) / (Scalar)2;
        sxy += da * (u_ring[head >= k ? head - k : head - k + D + 1] - v);
        sxx += da * da;
      }
      *slope = sxx > (Scalar)0 ? -sxy / (dt * sxx) : (Scalar)0;
    }
  }
  if (interpolate) {
    v = (v - lo) / step;
    v = v <= (Scalar)0 ? (Scalar)0 : v >= (Scalar)(levels - 1) ? (Scalar)(levels - 1) : v;
    *level = (int)OBSYNTH_C_FLOOR(v);
    if (*level > levels - 2) *level = levels - 2;
    *frac = v - (Scalar)*level;
  } else {
    v = OBSYNTH_C_FLOOR((v - lo) / step + (nearest ? (Scalar)0.5 : (Scalar)0));
    *level = v <= (Scalar)0 ? 0 : v >= (Scalar)(levels - 1) ? levels - 1 : (int)v;
  }
}

/* The grid of states a finite-time observer's tables are computed on: n axes of grid_count[s]
 * points from grid_lo[s] in steps grid_step[s], the last axis fastest. */
typedef struct {
  int n, points;
  const Scalar* lo;
  const Scalar* step;
  const int* count;
} obsynth_delay_grid;

/* The estimate: eta = M (z_now - delay .* z_old) from the newest and the oldest slot, then the
 * kernel-weighted mean over the grid of the level's table q (filters values per grid point),
 *   x = sum_i x_i w_i / sum_i w_i,  w_i = (epsilon + |eta - q(x_i)|)^-power,
 * with q interpolated towards q1 by frac and corrected by slope times the slope tables dq, dq1
 * (q1, dq, dq1 may be null: not read). work: 2 filters Scalars, idx: n ints. */
static inline void obsynth_delay_estimate(const obsynth_delay_grid* g, const Scalar* ring, int head,
                                          int D, int filters, const Scalar* delay,
                                          const Scalar* metric, const Scalar* q, const Scalar* q1,
                                          Scalar frac, const Scalar* dq, const Scalar* dq1,
                                          Scalar slope, Scalar epsilon, int power, Scalar* work,
                                          int* idx, Scalar* x) {
  const int old = head == D ? 0 : head + 1; /* D samples ago */
  Scalar *raw = work, *eta = work + filters, sw = (Scalar)0;
  int i, j, k, s;
  for (j = 0; j < filters; ++j)
    raw[j] = ring[head * filters + j] - delay[j] * ring[old * filters + j];
  for (j = 0; j < filters; ++j) {
    eta[j] = (Scalar)0;
    for (k = 0; k < filters; ++k) eta[j] += metric[j * filters + k] * raw[k];
  }
  for (s = 0; s < g->n; ++s) {
    idx[s] = 0;
    x[s] = (Scalar)0;
  }
  for (i = 0; i < g->points; ++i) {
    const long at = (long)i * filters;
    Scalar d2 = (Scalar)0, b, w;
    for (j = 0; j < filters; ++j) {
      Scalar e = q[at + j];
      if (q1) e += frac * (q1[at + j] - q[at + j]);
      if (dq) e += slope * (dq[at + j] + frac * (dq1[at + j] - dq[at + j]));
      e -= eta[j];
      d2 += e * e;
    }
    b = (Scalar)1 / (epsilon + OBSYNTH_C_SQRT(d2));
    w = b;
    for (k = 1; k < power; ++k) w *= b;
    sw += w;
    for (s = 0; s < g->n; ++s) x[s] += w * (g->lo[s] + g->step[s] * (Scalar)idx[s]);
    for (s = g->n - 1; s >= 0; --s) { /* last axis fastest */
      if (++idx[s] < g->count[s]) break;
      idx[s] = 0;
    }
  }
  for (s = 0; s < g->n; ++s) x[s] /= sw;
}

#endif /* OBSYNTH_C_KERNELS_BODY */
