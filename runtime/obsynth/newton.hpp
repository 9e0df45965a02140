// SPDX-License-Identifier: MIT
// Copyright (c) obsynth authors
//
// Newton's method for T(x) = z: inverts an observer diffeomorphism at run time.
//
// An observer that runs in transformed coordinates z must map its estimate back,
// xh = T^{-1}(zh). When no closed form of T^{-1} is available, it is computed by Newton's
// method seeded with the previous estimate. Because zh moves by O(dt) per step, the seed is
// already within O(dt) of the answer and a couple of iterations reach working precision
// (quadratic convergence).
//
// Two variants:
//
//  (a) newton_solve_inverse_jacobian: the caller supplies the inverse Jacobian directly. For
//      the canonical-form observers this is the frame [tau](x) = (dT/dx)^{-1}
//      (dT/dx * [tau_1 ... tau_n] = I), which the synthesizer has in closed form, so no
//      linear solve is needed:      x <- x - tau(x) (T(x) - z).
//  (b) newton_solve_jacobian: the caller supplies dT/dx; each step solves
//      (dT/dx) dx = T(x) - z with a fixed-size Eigen::PartialPivLU (stack storage only).
//
// Callables (taken by forwarding reference so they can be inlined; must be noexcept):
//   void T(const Vector<Scalar,N>& x, Vector<Scalar,N>& Tx) noexcept;
//   void inverse_jacobian(const Vector<Scalar,N>& x, Matrix<Scalar,N,N>& tau) noexcept;  // (a)
//   void jacobian(const Vector<Scalar,N>& x, Matrix<Scalar,N,N>& J) noexcept;           // (b)
//
// Stopping rule. With the residual r = T(x) - z and the max-norm |.|_inf, the iteration
// stops successfully as soon as
//       |r|_inf <= tol * (1 + |z|_inf)
// i.e. tol is an absolute tolerance for |z| <~ 1 and a relative one for large |z|. The
// residual of the *returned* x is always evaluated, so the seed itself may already satisfy
// the test (0 iterations). Choose tol above the rounding floor of T: a few times
// machine epsilon (float: ~1e-6, double: ~1e-13) times the condition of the evaluation.
//
// Outcome (NewtonResult):
//   ok                    converged; x is the solution, residual_norm = |r|_inf at x.
//   newton_not_converged  max_iterations updates applied without meeting the test; x is the
//                         last iterate (finite), residual_norm its residual.
//   non_finite            T, the (inverse) Jacobian or an update produced NaN/Inf (or the
//                         seed or z was non-finite); x is left at the last iterate whose
//                         residual was finite (the seed if that already failed), and
//                         residual_norm is that iterate's residual (or NaN if none).
//   singular              (b) only: dT/dx had a pivot that was zero or below
//                         N * eps * (largest pivot); x is left at the current iterate.
// iterations counts the Newton updates computed, including a last one that was rolled back
// because it led to a non-finite residual.
#pragma once

#include <limits>
#include <type_traits>

#include "obsynth/c_kernels.hpp"
#include "obsynth/eigen.hpp"
#include "obsynth/numeric.hpp"
#include "obsynth/status.hpp"

namespace obsynth {

/// Outcome of a Newton solve.
template <class Scalar>
struct NewtonResult {
  Status status = Status::ok;
  int iterations = 0;                ///< Newton updates computed (see above)
  Scalar residual_norm = Scalar(0);  ///< |T(x) - z|_inf at the returned x
};

namespace detail {

template <class Fn, class Scalar, int N>
constexpr void check_map() noexcept {
  static_assert(N > 0, "obsynth Newton solvers need a fixed, positive dimension");
  static_assert(std::is_nothrow_invocable_v<Fn&, const Eigen::Matrix<Scalar, N, 1>&,
                                            Eigen::Matrix<Scalar, N, 1>&>,
                "T must be callable as T(const Matrix<Scalar,N,1>& x, Matrix<Scalar,N,1>& Tx) "
                "and be noexcept");
}

template <class Fn, class Scalar, int N>
constexpr void check_matrix_fn() noexcept {
  static_assert(std::is_nothrow_invocable_v<Fn&, const Eigen::Matrix<Scalar, N, 1>&,
                                            Eigen::Matrix<Scalar, N, N>&>,
                "the (inverse) Jacobian must be callable as "
                "J(const Matrix<Scalar,N,1>& x, Matrix<Scalar,N,N>& J) and be noexcept");
}

/// The Newton loop: the C kernel's iteration (obsynth_newton_*, as the C back end and the
/// simulator run it). `update(x, r, dx)` computes the update dx for residual r at x and returns
/// Status::ok, Status::singular or Status::non_finite (a non-finite dx is caught by the next
/// residual, which puts x back at the last iterate).
template <class Scalar, int N, class TFn, class UpdateFn>
inline NewtonResult<Scalar> newton_loop(TFn& T, UpdateFn&& update,
                                        const Eigen::Matrix<Scalar, N, 1>& z,
                                        Eigen::Matrix<Scalar, N, 1>& x, int max_iterations,
                                        Scalar tol) noexcept {
  using Vec = Eigen::Matrix<Scalar, N, 1>;
  c::newton_state<Scalar> nw;
  c::newton_begin(&nw, z.data(), x.data(), N, max_iterations, tol);
  Vec Tx = Vec::Zero(), r, dx, x_prev = x;
  NewtonResult<Scalar> res;
  for (;;) {
    if (nw.status == c::newton_running) T(static_cast<const Vec&>(x), Tx);
    if (!c::newton_residual(&nw, Tx.data(), z.data(), N, r.data(), x.data(), x_prev.data())) break;
    res.status = update(static_cast<const Vec&>(x), static_cast<const Vec&>(r), dx);
    if (res.status != Status::ok) {
      res.iterations = nw.updates;
      res.residual_norm = nw.residual_norm;
      return res;
    }
    c::newton_apply(&nw, dx.data(), N, x.data(), x_prev.data());
  }
  res.status = nw.status == c::newton_converged       ? Status::ok
               : nw.status == c::newton_not_converged ? Status::newton_not_converged
                                                      : Status::non_finite;
  res.iterations = nw.updates;
  res.residual_norm = nw.updates == 0 && res.status == Status::non_finite
                          ? std::numeric_limits<Scalar>::quiet_NaN()
                          : nw.residual_norm;
  return res;
}

}  // namespace detail

/// Newton for T(x) = z with a caller-supplied inverse Jacobian tau(x) = (dT/dx)^{-1}:
///   x <- x - tau(x) (T(x) - z).
/// x is the seed on entry (use the previous estimate) and the result on return.
template <class Scalar, int N, class TFn, class InvJacFn>
inline NewtonResult<Scalar> newton_solve_inverse_jacobian(
    TFn&& T, InvJacFn&& inverse_jacobian, const Eigen::Matrix<Scalar, N, 1>& z,
    Eigen::Matrix<Scalar, N, 1>& x, int max_iterations,
    detail::type_identity_t<Scalar> tol) noexcept {
  detail::check_map<TFn, Scalar, N>();
  detail::check_matrix_fn<InvJacFn, Scalar, N>();
  using Vec = Eigen::Matrix<Scalar, N, 1>;
  using Mat = Eigen::Matrix<Scalar, N, N>;
  auto step = [&inverse_jacobian](const Vec& xi, const Vec& r, Vec& dx) noexcept {
    Mat tau;
    inverse_jacobian(xi, tau);
    c::newton_step(tau.data(), r.data(), N, dx.data());
    return Status::ok;  // non-finite tau shows up as a non-finite dx
  };
  return detail::newton_loop<Scalar, N>(T, step, z, x, max_iterations, tol);
}

/// Newton for T(x) = z with a caller-supplied Jacobian J(x) = dT/dx, solved by fixed-size
/// partial-pivoting LU: x <- x - J(x)^{-1} (T(x) - z).
/// x is the seed on entry (use the previous estimate) and the result on return.
template <class Scalar, int N, class TFn, class JacFn>
inline NewtonResult<Scalar> newton_solve_jacobian(TFn&& T, JacFn&& jacobian,
                                                  const Eigen::Matrix<Scalar, N, 1>& z,
                                                  Eigen::Matrix<Scalar, N, 1>& x,
                                                  int max_iterations,
                                                  detail::type_identity_t<Scalar> tol) noexcept {
  detail::check_map<TFn, Scalar, N>();
  detail::check_matrix_fn<JacFn, Scalar, N>();
  using Vec = Eigen::Matrix<Scalar, N, 1>;
  using Mat = Eigen::Matrix<Scalar, N, N>;
  auto step = [&jacobian](const Vec& xi, const Vec& r, Vec& dx) noexcept {
    Mat J;
    jacobian(xi, J);
    if (!all_finite(J)) return Status::non_finite;
    const Eigen::PartialPivLU<Mat> lu(J);
    // Partial pivoting puts the largest available entry on the diagonal of U; a zero or
    // relatively tiny pivot means J is singular to working precision.
    const auto pivots = lu.matrixLU().diagonal().cwiseAbs();
    const Scalar max_pivot = pivots.maxCoeff();
    const Scalar min_pivot = pivots.minCoeff();
    if (!(max_pivot > Scalar(0)) ||
        min_pivot <= Scalar(N) * std::numeric_limits<Scalar>::epsilon() * max_pivot) {
      return Status::singular;
    }
    dx = lu.solve(r);
    return Status::ok;
  };
  return detail::newton_loop<Scalar, N>(T, step, z, x, max_iterations, tol);
}

}  // namespace obsynth
