// SPDX-License-Identifier: MIT
// Copyright (c) obsynth authors
//
// Factorised solves and packed symmetric blocks for observers whose state holds a matrix
// (Riccati Q, Kalman-like S) or whose gain needs M^-1 v (high-gain O(x)^-1). Fixed size,
// no heap, noexcept, failure as `false` (the caller turns it into a Status). The factorisations
// are the C99 kernels of obsynth/c/kernels.h (Cholesky; LU with partial pivoting and its
// conditioning limit), the same text the C back end and the simulator run; never an explicit
// inverse.
#pragma once

#include <cmath>
#include <type_traits>

#include "obsynth/c_kernels.hpp"
#include "obsynth/eigen.hpp"
#include "obsynth/numeric.hpp"

namespace obsynth {

/// The symmetric D x D matrix stored row by row as its packed upper triangle at
/// w[offset, offset + D(D+1)/2): (0,0), (0,1), ..., (0,D-1), (1,1), ..., (D-1,D-1).
template <int Offset, int D, class Scalar, int NW>
inline void unpack_symmetric(const Eigen::Matrix<Scalar, NW, 1>& w,
                             Eigen::Matrix<Scalar, D, D>& M) noexcept {
  static_assert(Offset + D * (D + 1) / 2 <= NW, "packed block outside the observer state");
  int k = Offset;
  for (int r = 0; r < D; ++r)
    for (int c = r; c < D; ++c) {
      M(r, c) = w(k);
      M(c, r) = w(k);
      ++k;
    }
}

/// Whether the packed symmetric block is (numerically) positive definite: the pivots of its
/// square-root-free Cholesky factorisation M = L D L^T (no pivoting) are all finite and > 0,
/// which is exactly when the Cholesky factorisation (LLT) exists. Reads the packed triangle
/// in place: no unpacking, no square roots, one division per column.
template <int Offset, int D, class Scalar, int NW>
inline bool packed_positive_definite(const Eigen::Matrix<Scalar, NW, 1>& w) noexcept {
  static_assert(Offset + D * (D + 1) / 2 <= NW, "packed block outside the observer state");
  static_assert(std::is_same<Scalar, float>::value || std::is_same<Scalar, double>::value,
                "packed_positive_definite: float or double");
  Scalar work[D * D + D];  // the C kernel's L and D (runtime/obsynth/c/kernels.h)
  return c::packed_positive_definite(w.data(), Offset, D, work) != 0;
}

/// x = M^-1 v for symmetric positive definite M (Cholesky). False when M is not positive
/// definite or the result is not finite.
template <class Scalar, int D>
inline bool solve_cholesky(const Eigen::Matrix<Scalar, D, D>& M,
                           const Eigen::Matrix<Scalar, D, 1>& v,
                           Eigen::Matrix<Scalar, D, 1>& x) noexcept {
  Scalar a[D * D];  // row-major copy: the kernel factorises in place
  for (int r = 0; r < D; ++r)
    for (int c = 0; c < D; ++c) a[r * D + c] = M(r, c);
  return c::solve_cholesky(a, D, v.data(), x.data()) != 0;
}

/// The ill-conditioning limit of solve_lu: sqrt(epsilon) of the scalar type (2^-26 = 1.49e-8 for
/// double, 3.45e-4 for float). A matrix whose smallest LU pivot is at most this fraction of its
/// largest one has an (estimated) condition number of at least epsilon^(-1/2): the solve's
/// relative error bound kappa * epsilon exceeds sqrt(epsilon), so at least half of the working
/// digits of M^-1 v are lost. This is Dennis and Schnabel's test for treating the Jacobian of
/// a Newton step as singular (Numerical Methods for Unconstrained Optimization and Nonlinear
/// Equations, 1983, sec. 6.5); the high-gain observer's O(xh)^-1 v is such a step (O = dPhi/dx
/// maps a correction of z = Phi(x) to one of x).
template <class Scalar>
inline Scalar lu_conditioning_limit() noexcept {
  return std::sqrt(Eigen::NumTraits<Scalar>::epsilon());
}

/// x = M^-1 v by LU with partial pivoting. False when the smallest pivot is at most
/// lu_conditioning_limit<Scalar>() = sqrt(epsilon) times the largest one (ill-conditioned at
/// this precision; this also covers a pivot below D * epsilon, singular to working precision),
/// when M is not finite, or when the result is not finite.
template <class Scalar, int D>
inline bool solve_lu(const Eigen::Matrix<Scalar, D, D>& M, const Eigen::Matrix<Scalar, D, 1>& v,
                     Eigen::Matrix<Scalar, D, 1>& x) noexcept {
  Scalar a[D * D];  // row-major copy: the kernel factorises in place
  for (int r = 0; r < D; ++r)
    for (int c = 0; c < D; ++c) a[r * D + c] = M(r, c);
  return c::solve_lu(a, D, v.data(), x.data()) != 0;
}

}  // namespace obsynth
