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

/// true when every coefficient of an Eigen expression is finite.
template <class Derived>
inline bool all_finite(const Eigen::MatrixBase<Derived>& m) noexcept {
  using Scalar = typename Derived::Scalar;
  for (Eigen::Index j = 0; j < m.cols(); ++j) {
    for (Eigen::Index i = 0; i < m.rows(); ++i) {
      if (!is_finite<Scalar>(m.coeff(i, j))) return false;
    }
  }
  return true;
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
