// SPDX-License-Identifier: MIT
// Copyright (c) obsynth authors
#pragma once

#include "obsynth/status.hpp"

template <class Scalar>
struct StrictResult {
  Scalar euler_error = 0;
  Scalar heun_error = 0;
  Scalar rk4_error = 0;
  Scalar newton_error = 0;
  Scalar differentiator_error = 0;
  obsynth::Status newton_status = obsynth::Status::ok;
  obsynth::Status observer_status = obsynth::Status::ok;
};

// Defined in strict_instantiation.cpp (built with the generated-code contract flags).
StrictResult<float> strict_exercise_float() noexcept;
StrictResult<double> strict_exercise_double() noexcept;
