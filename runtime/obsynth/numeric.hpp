// SPDX-License-Identifier: MIT
// Copyright (c) obsynth authors
//
// Small numeric helpers shared by the runtime and by generated observers.
//
// Finiteness is tested on the IEEE-754 bit pattern (exponent field all ones means Inf or
// NaN) rather than with std::isfinite or x == x, so the check keeps working when firmware is
// built with -ffast-math / -ffinite-math-only, under which the compiler may assume that NaN
// and Inf never occur and fold the usual tests to "true".
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <type_traits>

#include "obsynth/eigen.hpp"

namespace obsynth {

/// true when x is neither NaN nor +-Inf. Robust under -ffinite-math-only for float and
/// double (IEEE-754 binary32/binary64); other scalar types fall back to std::isfinite.
template <class Scalar>
inline bool is_finite(Scalar x) noexcept {
  if constexpr (std::numeric_limits<Scalar>::is_iec559 && sizeof(Scalar) == 4) {
    std::uint32_t bits = 0;
    std::memcpy(&bits, &x, sizeof bits);
    return (bits & UINT32_C(0x7f800000)) != UINT32_C(0x7f800000);
  } else if constexpr (std::numeric_limits<Scalar>::is_iec559 && sizeof(Scalar) == 8) {
    std::uint64_t bits = 0;
    std::memcpy(&bits, &x, sizeof bits);
    return (bits & UINT64_C(0x7ff0000000000000)) != UINT64_C(0x7ff0000000000000);
  } else {
    return std::isfinite(x);
  }
}

namespace detail {
/// The IEEE-754 bit layout of float and double for the branch-free finiteness test:
/// |x|'s bits (bits & magnitude) are >= the bits of +Inf exactly when x is Inf or NaN, so
/// (bits & magnitude) + step, with step = 2^(mantissa bits), reaches the sign bit (top) exactly
/// then; no finite value's sum does. OR-ing these sums over many values tests them all at once.
template <class Scalar, class = void>
struct finite_bits {
  static constexpr bool available = false;
};
template <class Scalar>
struct finite_bits<Scalar, std::enable_if_t<std::numeric_limits<Scalar>::is_iec559 &&
                                            sizeof(Scalar) == sizeof(std::uint32_t)>> {
  static constexpr bool available = true;
  using U = std::uint32_t;
  static constexpr U magnitude = UINT32_C(0x7fffffff);
  static constexpr U step = UINT32_C(0x00800000);
  static constexpr U top = UINT32_C(0x80000000);
};
template <class Scalar>
struct finite_bits<Scalar, std::enable_if_t<std::numeric_limits<Scalar>::is_iec559 &&
                                            sizeof(Scalar) == sizeof(std::uint64_t)>> {
  static constexpr bool available = true;
  using U = std::uint64_t;
  static constexpr U magnitude = UINT64_C(0x7fffffffffffffff);
  static constexpr U step = UINT64_C(0x0010000000000000);
  static constexpr U top = UINT64_C(0x8000000000000000);
};

/// OR over the coefficients of m of (bits & magnitude) + step: top is set iff one is not finite.
template <class Derived>
inline typename finite_bits<typename Derived::Scalar>::U nonfinite_flags(
    const Eigen::MatrixBase<Derived>& m) noexcept {
  using Scalar = typename Derived::Scalar;
  using B = finite_bits<Scalar>;
  typename B::U acc = 0;
  for (Eigen::Index j = 0; j < m.cols(); ++j) {
    for (Eigen::Index i = 0; i < m.rows(); ++i) {
      const Scalar x = m.coeff(i, j);
      typename B::U bits = 0;
      std::memcpy(&bits, &x, sizeof bits);
      acc |= (bits & B::magnitude) + B::step;
    }
  }
  return acc;
}

template <class Derived>
inline bool all_finite_loop(const Eigen::MatrixBase<Derived>& m) noexcept {
  for (Eigen::Index j = 0; j < m.cols(); ++j) {
    for (Eigen::Index i = 0; i < m.rows(); ++i) {
      if (!std::isfinite(m.coeff(i, j))) return false;
    }
  }
  return true;
}
}  // namespace detail

/// true when every coefficient of the Eigen expressions given (one or more, of one scalar type)
/// is finite. For float and double: one branch-free pass over all of them (the bit test of
/// is_finite, OR-ed; the usual case, all finite, needs no early exit), robust under
/// -ffinite-math-only like is_finite.
template <class Derived, class... More>
inline bool all_finite(const Eigen::MatrixBase<Derived>& m,
                       const Eigen::MatrixBase<More>&... more) noexcept {
  using Scalar = typename Derived::Scalar;
  static_assert((std::is_same_v<Scalar, typename More::Scalar> && ...),
                "all_finite: one scalar type for all arguments");
  using B = detail::finite_bits<Scalar>;
  if constexpr (B::available) {
    const typename B::U acc = (detail::nonfinite_flags(m) | ... | detail::nonfinite_flags(more));
    return (acc & B::top) == 0;
  } else {
    return detail::all_finite_loop(m) && (detail::all_finite_loop(more) && ...);
  }
}

/// Infinity norm (max |v_i|) of a vector; 0 for an empty vector.
template <class Derived>
inline typename Derived::Scalar inf_norm(const Eigen::MatrixBase<Derived>& v) noexcept {
  using Scalar = typename Derived::Scalar;
  Scalar r = Scalar(0);
  for (Eigen::Index i = 0; i < v.size(); ++i) {
    const Scalar a = std::abs(v.coeff(i));
    // a NaN coefficient propagates into the result (checked on the bit pattern)
    r = (a > r || !is_finite<Scalar>(a)) ? a : r;
  }
  return r;
}

namespace detail {
/// Identity metafunction: makes a parameter a non-deduced context, so that e.g. a double
/// literal passed as dt does not conflict with Scalar = float deduced from the state.
template <class T>
struct type_identity {
  using type = T;
};
template <class T>
using type_identity_t = typename type_identity<T>::type;
}  // namespace detail

}  // namespace obsynth
