// SPDX-License-Identifier: MIT
// Copyright (c) obsynth authors
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "../../bench/handwritten_seed003.hpp"
#include "obsynth/numeric.hpp"
#include "obsynth/observer.hpp"
#include "obsynth/status.hpp"

namespace {

using obsynth::Status;

// A minimal conforming observer (n = 3, no inputs, p = 1).
struct Minimal {
  using Scalar = float;
  static constexpr int n = 3;
  static constexpr int m = 0;
  static constexpr int p = 1;
  using State = Eigen::Matrix<float, 3, 1>;
  using Input = Eigen::Matrix<float, 0, 1>;
  using Output = Eigen::Matrix<float, 1, 1>;
  void reset(const State& x) noexcept { x_ = x; }
  Status step(Scalar, const Input&, const Output&) noexcept { return Status::ok; }
  const State& estimate() const noexcept { return x_; }
  Status status() const noexcept { return Status::ok; }
  State x_ = State::Zero();
};

struct MissingStatus : Minimal {
  void status() = delete;
};

struct ThrowingStep : Minimal {
  Status step(Scalar, const Input&, const Output&) { return Status::ok; }
};

struct BoolStep : Minimal {
  bool step(Scalar, const Input&, const Output&) noexcept { return true; }
};

struct EstimateByValue : Minimal {
  State estimate() const noexcept { return x_; }
};

struct WrongStateSize : Minimal {
  using State = Eigen::Matrix<float, 2, 1>;
  void reset(const State&) noexcept {}
  const State& estimate() const noexcept { return s_; }
  State s_;
};

struct DynamicState : Minimal {
  using State = Eigen::Matrix<float, Eigen::Dynamic, 1>;
  void reset(const State&) noexcept {}
  const State& estimate() const noexcept { return s_; }
  State s_;
};

struct MixedScalar : Minimal {
  using Output = Eigen::Matrix<double, 1, 1>;
  Status step(Scalar, const Input&, const Output&) noexcept { return Status::ok; }
};

struct NonConstexprDims : Minimal {
  static const long n = 3;
};

struct NoTypes {
  void reset() noexcept {}
};

static_assert(obsynth::is_observer_v<Minimal>);
static_assert(obsynth::is_observer_v<const Minimal>);
static_assert(obsynth::is_observer_v<handwritten::seed003::CanonicalObserver<float>>);
static_assert(obsynth::is_observer_v<handwritten::seed003::CanonicalObserver<double>>);
static_assert(!obsynth::is_observer_v<MissingStatus>);
static_assert(!obsynth::is_observer_v<ThrowingStep>);
static_assert(!obsynth::is_observer_v<BoolStep>);
static_assert(!obsynth::is_observer_v<EstimateByValue>);
static_assert(!obsynth::is_observer_v<WrongStateSize>);
static_assert(!obsynth::is_observer_v<DynamicState>);
static_assert(!obsynth::is_observer_v<MixedScalar>);
static_assert(!obsynth::is_observer_v<NonConstexprDims>);
static_assert(!obsynth::is_observer_v<NoTypes>);
static_assert(!obsynth::is_observer_v<int>);
static_assert(!obsynth::is_observer_v<Eigen::Matrix<float, 2, 1>>);

TEST(ObserverTrait, StaticChecksCompiled) {
  EXPECT_TRUE(obsynth::is_observer<Minimal>::value);
  EXPECT_FALSE(obsynth::is_observer<ThrowingStep>::value);
}

TEST(Status, NamesAreStable) {
  EXPECT_STREQ(obsynth::status_name(Status::ok), "ok");
  EXPECT_STREQ(obsynth::status_name(Status::newton_not_converged), "newton_not_converged");
  EXPECT_STREQ(obsynth::status_name(Status::non_finite), "non_finite");
  EXPECT_STREQ(obsynth::status_name(Status::singular), "singular");
  EXPECT_STREQ(obsynth::status_name(static_cast<Status>(200)), "unknown");
  static_assert(sizeof(Status) == 1);
  static_assert(obsynth::status_name(Status::ok)[0] == 'o');
  static_assert(obsynth::worst(Status::ok, Status::non_finite) == Status::non_finite);
  static_assert(obsynth::worst(Status::singular, Status::ok) == Status::singular);
}

}  // namespace

namespace {

// all_finite over one or several vectors against std::isfinite on every value (an oracle that
// shares no code with the bit test): every combination of the IEEE-754 edge cases, float,
// double, and long double (the std::isfinite fallback).
template <class S>
int all_finite_mismatches() {
  using L = std::numeric_limits<S>;
  const S values[] = {S(0),           -S(0),          L::denorm_min(), -L::denorm_min(),
                      L::min(),       L::max(),       -L::max(),       L::infinity(),
                      -L::infinity(), L::quiet_NaN(), -L::quiet_NaN(), L::signaling_NaN(),
                      S(1),           S(-3.5)};
  int bad = 0;
  for (S a : values)
    for (S b : values)
      for (S c : values) {
        const Eigen::Matrix<S, 2, 1> v(a, b);
        Eigen::Matrix<S, 1, 1> w;
        w << c;
        const bool ab = std::isfinite(a) && std::isfinite(b);
        bad += obsynth::all_finite(v) != ab;
        bad += obsynth::all_finite(v, w) != (ab && std::isfinite(c));
        bad += obsynth::all_finite(w, v, w) != (ab && std::isfinite(c));
      }
  return bad;
}

}  // namespace

TEST(Numeric, AllFiniteMatchesIsfiniteOnEdgeCases) {
  EXPECT_EQ(all_finite_mismatches<float>(), 0);
  EXPECT_EQ(all_finite_mismatches<double>(), 0);
  EXPECT_EQ(all_finite_mismatches<long double>(), 0);
}
