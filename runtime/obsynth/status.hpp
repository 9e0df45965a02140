// SPDX-License-Identifier: MIT
// Copyright (c) obsynth authors
//
// Numeric status codes returned by the obsynth runtime and by generated observers.
// Failures are reported as values, never as exceptions.
#pragma once

namespace obsynth {

/// Result of a numeric operation (an observer step, a Newton solve, a differentiator update).
enum class Status : unsigned char {
  ok,                    ///< success
  newton_not_converged,  ///< Newton hit its iteration cap; the result is the last finite iterate
  non_finite,            ///< a NaN or infinity appeared (or an input was invalid); state kept
  singular,              ///< a Jacobian (or frame) was singular to working precision
};

/// Stable, human-readable name of a status ("ok", "newton_not_converged", ...).
constexpr const char* status_name(Status s) noexcept {
  switch (s) {
    case Status::ok:
      return "ok";
    case Status::newton_not_converged:
      return "newton_not_converged";
    case Status::non_finite:
      return "non_finite";
    case Status::singular:
      return "singular";
  }
  return "unknown";
}

/// The worse of two statuses (ok < newton_not_converged < non_finite < singular), so that a
/// sequence of operations can accumulate one status: `s = worst(s, next_op())`.
constexpr Status worst(Status a, Status b) noexcept {
  return static_cast<unsigned char>(a) >= static_cast<unsigned char>(b) ? a : b;
}

}  // namespace obsynth
