// SPDX-License-Identifier: MIT
// Copyright (c) obsynth authors
//
// Runs the code of strict_instantiation.cpp, which was compiled with the generated-code
// contract flags (-fno-exceptions -fno-rtti -Werror -Wconversion -Wdouble-promotion ...).
#include <gtest/gtest.h>

#include "strict_instantiation.hpp"

namespace {

template <class Scalar>
void check(const StrictResult<Scalar>& r, double tol) {
  // One period of the oscillator with 200 steps: Euler grows by (1 + dt^2)^100 ~ 1.2,
  // Heun ~ 2 pi dt^2 / 6 ~ 1e-3, RK4 ~ 2 pi dt^4 / 120 ~ 1e-7.
  EXPECT_GT(r.euler_error, Scalar(0.1));
  EXPECT_LT(r.heun_error, Scalar(2e-3));
  EXPECT_LT(r.rk4_error, Scalar(tol));
  EXPECT_EQ(r.newton_status, obsynth::Status::ok);
  EXPECT_LT(r.newton_error, Scalar(tol));
  EXPECT_LT(r.differentiator_error, Scalar(0.01));  // 3 eps^2 |y'''| = 1.2e-3
  EXPECT_EQ(r.observer_status, obsynth::Status::ok);
}

TEST(StrictContract, FloatBuild) { check(strict_exercise_float(), 1e-4); }
TEST(StrictContract, DoubleBuild) { check(strict_exercise_double(), 1e-6); }

}  // namespace
