// An expert's step for any generated canonical observer in z coordinates, as the reference
// for the constructed chains (issue 7: the generated step against an expert one, n = 2..8).
// The expert reuses the generated nonlinear maps (l + K (y - y0) as step_constant, T,
// T^-1): their cost is the same in both. What it writes itself is the linear part, the way
// an expert writes it: the closed loop A_cl (read off the generated z_rhs, A_cl e_j =
// z_rhs(e_j, c = 0)), one RK4 step of the linear system folded into two n x n matrices
//   P = I + hA + (hA)^2/2 + (hA)^3/6 + (hA)^4/24,  Q = h (I + hA/2 + (hA)^2/6 + (hA)^3/24),
// refolded only when dt changes, and a step z <- P z + Q c, x = T^-1(z).
#pragma once

#include <type_traits>
#include <utility>

#include "obsynth/eigen.hpp"
#include "obsynth/numeric.hpp"
#include "obsynth/status.hpp"

namespace obsynth_bench {

template <class F, class = void>
struct has_closed_form_z : std::false_type {};
template <class F>
struct has_closed_form_z<F,
                         std::void_t<decltype(F::T_inverse(std::declval<const typename F::State&>(),
                                                           std::declval<typename F::State&>())),
                                     decltype(F::z_rhs(std::declval<const typename F::State&>(),
                                                       std::declval<const typename F::State&>(),
                                                       std::declval<typename F::State&>()))>>
    : std::true_type {};

template <class Gen>
class ExpertCanonical {
 public:
  using Scalar = typename Gen::Scalar;
  static constexpr int n = Gen::n;
  static constexpr int m = Gen::m;
  static constexpr int p = Gen::p;
  using State = typename Gen::State;
  using Input = typename Gen::Input;
  using Output = typename Gen::Output;
  using F = typename Gen::F;
  using Mat = Eigen::Matrix<Scalar, n, n>;

  ExpertCanonical() noexcept {
    const State zero = State::Zero();
    for (int j = 0; j < n; ++j) {
      State e = State::Zero(), col;
      e(j) = Scalar(1);
      F::z_rhs(e, zero, col);
      A_.col(j) = col;
    }
  }

  void reset(const State& xh0) noexcept {
    F::T(xh0, z_);
    xh_ = xh0;
    status_ = obsynth::Status::ok;
  }

  obsynth::Status step(Scalar dt, const Input& u, const Output& y) noexcept {
    if (dt != dt_) fold(dt);
    State c;
    F::step_constant(u, y, c);
    const State z = P_ * z_ + Q_ * c;
    State x;
    F::T_inverse(z, x);
    if (!obsynth::all_finite(z) || !obsynth::all_finite(x))
      return status_ = obsynth::Status::non_finite;
    z_ = z;
    xh_ = x;
    return status_ = obsynth::Status::ok;
  }

  const State& estimate() const noexcept { return xh_; }
  obsynth::Status status() const noexcept { return status_; }

 private:
  void fold(Scalar h) noexcept {
    const Mat I = Mat::Identity();
    const Mat hA = h * A_, hA2 = hA * hA, hA3 = hA2 * hA, hA4 = hA3 * hA;
    P_ = I + hA + hA2 / Scalar(2) + hA3 / Scalar(6) + hA4 / Scalar(24);
    Q_ = h * (I + hA / Scalar(2) + hA2 / Scalar(6) + hA3 / Scalar(24));
    dt_ = h;
  }

  Mat A_, P_, Q_;
  Scalar dt_ = Scalar(0);
  State z_ = State::Zero(), xh_ = State::Zero();
  obsynth::Status status_ = obsynth::Status::ok;
};

}  // namespace obsynth_bench
