// The three-valued zero test (design.md §5): proved / numeric / nonzero.
#include <gtest/gtest.h>

#include "front/parse.hpp"
#include "symbolic/zero_test.hpp"

using namespace obsynth;
using GiNaC::ex;

namespace {

GiNaC::symbol x("x"), y("y");

ZeroVerdict verdict(const ex& e, SampleBoxes boxes = {}) {
  return zero_test(e, boxes);
}

SampleBoxes positive() {
  SampleBoxes b;
  b.by_name["x"] = {GiNaC::numeric(1, 2), GiNaC::numeric(2)};
  b.by_name["y"] = {GiNaC::numeric(1, 2), GiNaC::numeric(2)};
  return b;
}

TEST(ZeroTest, PythagoreanIdentityIsProved) {
  EXPECT_EQ(verdict(pow(sin(x), 2) + pow(cos(x), 2) - 1), ZeroVerdict::proved);
}

TEST(ZeroTest, SqrtOfSquareIsNotTheIdentity) {
  EXPECT_EQ(verdict(sqrt(pow(x, 2)) - x), ZeroVerdict::nonzero);
}

TEST(ZeroTest, TrigAndExpIdentitiesAreProved) {
  EXPECT_EQ(verdict(sin(2 * x) - 2 * sin(x) * cos(x)), ZeroVerdict::proved);
  EXPECT_EQ(verdict(cos(3 * x) - (4 * pow(cos(x), 3) - 3 * cos(x))), ZeroVerdict::proved);
  EXPECT_EQ(verdict(tan(x) - sin(x) / cos(x)), ZeroVerdict::proved);
  EXPECT_EQ(verdict(cos(x + y) - (cos(x) * cos(y) - sin(x) * sin(y))), ZeroVerdict::proved);
  EXPECT_EQ(verdict(exp(2 * x) - pow(exp(x), 2)), ZeroVerdict::proved);
  EXPECT_EQ(verdict(exp(x + y) - exp(x) * exp(y)), ZeroVerdict::proved);
  EXPECT_EQ(verdict(exp(x / 2) * exp(x / 3) - exp(5 * x / 6)), ZeroVerdict::proved);
  EXPECT_EQ(verdict(tanh(x) - (exp(2 * x) - 1) / (exp(2 * x) + 1)), ZeroVerdict::proved);
  EXPECT_EQ(verdict(pow(sin(x / 2), 2) - (1 - cos(x)) / 2), ZeroVerdict::proved);
}

TEST(ZeroTest, RationalFunctionsAreProved) {
  EXPECT_EQ(verdict((x * x - y * y) / (x - y) - x - y), ZeroVerdict::proved);
  EXPECT_EQ(verdict(ex(0)), ZeroVerdict::proved);
}

TEST(ZeroTest, IdentitiesBeyondTheRewriteAreNumeric) {
  // log(x y) = log x + log y only for positive x, y: not provable by the rewrite, zero on
  // the positive box.
  EXPECT_EQ(verdict(log(x * y) - log(x) - log(y), positive()), ZeroVerdict::numeric);
  EXPECT_EQ(verdict(atan(x) + atan(1 / x) - GiNaC::Pi / 2, positive()), ZeroVerdict::numeric);
}

TEST(ZeroTest, BranchDependentIdentitiesAreNonzeroOnTheDomain) {
  // atan(tan x) = x only on (-pi/2, pi/2); the default box [-2, 2] reaches beyond.
  EXPECT_EQ(verdict(atan(tan(x)) - x), ZeroVerdict::nonzero);
  EXPECT_EQ(verdict(sin(x) - x), ZeroVerdict::nonzero);
  EXPECT_EQ(verdict(ex(1) / 1000000000), ZeroVerdict::nonzero);
}

TEST(ZeroTest, SmallButNonzeroValuesAreNotMistakenForZero) {
  // 1e-12 * x is tiny on the box but clearly not zero at 40 digits.
  EXPECT_EQ(verdict(x / GiNaC::numeric(1000000000000LL)), ZeroVerdict::nonzero);
}

TEST(ZeroTest, DecimalsParseExactly) {
  const Model m = parse_model("model d\nstates x\nf = [0.1*3*x - 0.3*x]\nh = [x]\n", "d.sym");
  EXPECT_TRUE(m.f[0].is_zero());
}

TEST(ZeroTest, DigitsAreRestored) {
  const long before = GiNaC::Digits;
  (void)verdict(sin(x) - x);
  EXPECT_EQ(static_cast<long>(GiNaC::Digits), before);
}

}  // namespace
