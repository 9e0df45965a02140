// SPDX-License-Identifier: MIT
// Copyright (c) obsynth authors
//
// The single place where the obsynth runtime (and generated code) includes Eigen.
//
// Eigen 3.4 is not clean under the warning set that obsynth promises for its own code
// (-Wall -Wextra -Wconversion -Wdouble-promotion -pedantic, and stricter sets firmware
// projects often add: -Wold-style-cast, -Wcast-align, -Wuseless-cast, ...): for example with
// arm-none-eabi-g++ (whose ABI uses short enums) Eigen's internal flag enums trigger
// -Wconversion, and clang's -Wconversion includes -Wsign-conversion which fires inside
// Eigen's packet math. When Eigen is found through a plain -I (not -isystem) those
// warnings would break -Werror builds. The pragmas below silence them for Eigen's own
// source lines only; GCC and clang attribute template-instantiation warnings to the line of
// the template, so code that *uses* Eigen is still checked with the full warning set.
//
// Every other runtime header includes this file instead of <Eigen/Dense>.
#pragma once

#if defined(__GNUC__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wconversion"
#pragma GCC diagnostic ignored "-Wsign-conversion"
#pragma GCC diagnostic ignored "-Wdouble-promotion"
#pragma GCC diagnostic ignored "-Wfloat-conversion"
#pragma GCC diagnostic ignored "-Wshadow"
#pragma GCC diagnostic ignored "-Wpedantic"
#pragma GCC diagnostic ignored "-Wold-style-cast"
#pragma GCC diagnostic ignored "-Wcast-qual"
#pragma GCC diagnostic ignored "-Wfloat-equal"
#pragma GCC diagnostic ignored "-Wundef"
#pragma GCC diagnostic ignored "-Wcast-align"
#if !defined(__clang__)
#pragma GCC diagnostic ignored "-Wuseless-cast"
#pragma GCC diagnostic ignored "-Wnull-dereference"
#pragma GCC diagnostic ignored "-Wduplicated-branches"
#endif
#endif

#include <Eigen/Dense>

#if defined(__GNUC__)
#pragma GCC diagnostic pop
#endif

namespace obsynth {

/// Column vector of fixed size N.
template <class Scalar, int N>
using Vector = Eigen::Matrix<Scalar, N, 1>;

/// Fixed-size R x C matrix.
template <class Scalar, int R, int C>
using Matrix = Eigen::Matrix<Scalar, R, C>;

}  // namespace obsynth
