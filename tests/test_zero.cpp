// The three-valued zero test (design.md §5): proved / numeric / nonzero.
#include <gtest/gtest.h>

#include <cmath>

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

// Issue 17 item 6: C2 of a DC motor with friction tanh(100 w), w in [-800, 800], is
// (5000/9) tanh(100 w) sech^2(100 w), written as GiNaC differentiates it (1 - tanh^2). Uniform
// samples all fall where 1 - tanh^2 cancels to rounding noise; it is nonzero all the same.
ex steep_bracket(const ex& w, const ex& shift = 0) {
  const ex th = tanh(100 * (w - shift));
  return GiNaC::numeric(5000, 9) * th * (1 - pow(th, 2));
}

SampleBoxes speed_box() {
  SampleBoxes b;
  b.by_name["x"] = {GiNaC::numeric(-800), GiNaC::numeric(800)};
  return b;
}

// Evaluates e at x = value with GiNaC's evalf directly (not obsynth's evaluator).
double evalf_at(const ex& e, const ex& value) {
  const long saved = GiNaC::Digits;
  GiNaC::Digits = 50;
  const ex v = GiNaC::evalf(e.subs(x == value));
  GiNaC::Digits = saved;
  return GiNaC::ex_to<GiNaC::numeric>(v).to_double();
}

TEST(ZeroTest, SteepBracketIsNonzeroWhereItIsNotDegenerate) {
  // Hand check: tanh(1/2) = 0.4621172, sech^2(1/2) = 0.7864477, product * 5000/9 = 201.906.
  EXPECT_NEAR(evalf_at(steep_bracket(x), GiNaC::numeric(1, 200)), 201.906, 1e-3);
  const ZeroTestResult r = zero_test_detailed(steep_bracket(x), speed_box());
  ASSERT_EQ(r.verdict, ZeroVerdict::nonzero);
  // The witness is a point of the box where the bracket is clearly nonzero, by evalf.
  ASSERT_EQ(r.witness.count(x), 1u);
  const ex w = r.witness.at(x);
  EXPECT_LE(GiNaC::abs(GiNaC::ex_to<GiNaC::numeric>(GiNaC::evalf(w))), 800);
  EXPECT_GT(std::abs(evalf_at(steep_bracket(x), w)), 1e-6);
}

TEST(ZeroTest, SteepBracketAwayFromTheOriginIsNonzero) {
  // The same bracket centred at w = 300: the points scaled towards 0 do not help, the points
  // where tanh's argument is of order one do. Hand check: 201.906 at w = 300.005.
  EXPECT_NEAR(evalf_at(steep_bracket(x, 300), GiNaC::numeric(300005, 1000)), 201.906, 1e-3);
  const ZeroTestResult r = zero_test_detailed(steep_bracket(x, 300), speed_box());
  ASSERT_EQ(r.verdict, ZeroVerdict::nonzero);
  EXPECT_GT(std::abs(evalf_at(steep_bracket(x, 300), r.witness.at(x))), 1e-6);
}

TEST(ZeroTest, SteepIdentitiesStayProvedOrNumeric) {
  // An identity of the rewrite stays proved on the steep box...
  EXPECT_EQ(verdict(tanh(100 * x) - (exp(200 * x) - 1) / (exp(200 * x) + 1), speed_box()),
            ZeroVerdict::proved);
  EXPECT_EQ(verdict(pow(sin(100 * x), 2) + pow(cos(100 * x), 2) - 1, speed_box()),
            ZeroVerdict::proved);
  // ...and one beyond it (atan e^a + atan e^-a = pi/2 for every real a) stays numeric at the
  // scaled points too, with the count of points it vanished at.
  const ex id = atan(exp(100 * x)) + atan(exp(-100 * x)) - GiNaC::Pi / 2;
  const ZeroTestResult r = zero_test_detailed(id, speed_box());
  EXPECT_EQ(r.verdict, ZeroVerdict::numeric);
  EXPECT_GT(r.zero_points, ZeroTestOptions{}.points);
}

TEST(ZeroTest, ScaledPointsStayInTheBox) {
  const SampleBoxes b = positive();
  for (const auto& pt : scaled_points(log(x * y) + tanh(7 * x - 3), {x, y}, b, 1))
    for (const auto& s : {x, y}) {
      const GiNaC::numeric v = GiNaC::ex_to<GiNaC::numeric>(pt.at(s));
      EXPECT_TRUE(v >= GiNaC::numeric(1, 2) && v <= 2) << s << " = " << v;
    }
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
