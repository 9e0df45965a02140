// Where a model is defined on its box (synth/certify/definedness.hpp), against answers derived by
// hand: the zero of each divisor, the sign of each root's and log's argument, and the poles of
// tan, located in the box on paper.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "certify/definedness.hpp"
#include "front/parse.hpp"

using namespace obsynth;
using certify::DefinedStatus;

namespace {

certify::Definedness definedness_of(const std::string& f, const std::string& box,
                                    const std::string& h = "x1") {
  const std::string text =
      "model t\nstates x1 x2\nf = [ " + f + " ]\nh = [ " + h + " ]\ndomain " + box + "\n";
  return certify::check_definedness(parse_model(text, "t.sym"));
}

// Numbers printed in a finding's sub-box, "name in [a, b]".
std::pair<double, double> range_of(const std::string& sub_box, const std::string& name) {
  const auto at = sub_box.find(name + " in [");
  EXPECT_NE(at, std::string::npos) << sub_box;
  if (at == std::string::npos) return {NAN, NAN};
  const char* p = sub_box.c_str() + at + name.size() + 5;
  char* end = nullptr;
  const double a = std::strtod(p, &end);
  const double b = std::strtod(end + 1, nullptr);
  return {a, b};
}

TEST(Definedness, PolynomialModelIsDefinedWithNoConditions) {
  const auto d = definedness_of("x2, -x1 - x2^3", "x1 in [-1, 1], x2 in [-1, 1]");
  EXPECT_TRUE(d.findings.empty());
  EXPECT_TRUE(d.errors().empty());
  EXPECT_EQ(d.conditions, 0u);
}

TEST(Definedness, PoleInsideTheBoxIsProvedAtItsZero) {
  // f2 = -1/x1 on x1 in [-1, 1]: the divisor x1 vanishes at x1 = 0, inside the box.
  const auto d = definedness_of("x2, -1/x1", "x1 in [-1, 1], x2 in [-1, 1]");
  ASSERT_EQ(d.findings.size(), 1u);
  const auto& f = d.findings[0];
  EXPECT_EQ(f.component, "f2");
  EXPECT_EQ(f.status, DefinedStatus::violated_somewhere);
  EXPECT_NE(f.requirement.find("x1 != 0"), std::string::npos) << f.requirement;
  EXPECT_NE(f.sub_box.find("x1 = 0"), std::string::npos) << f.sub_box;
  EXPECT_EQ(f.loc.line, 3);
  EXPECT_TRUE(d.undefined_somewhere());
  EXPECT_TRUE(d.errors().empty());  // defined on most of the box: designs exclude themselves
}

TEST(Definedness, TheVanishingFactorOfADivisorIsNamed) {
  // x1 x2 - x1 + x2 - 1 = (x1 + 1)(x2 - 1): on x1 in [-2, 2], x2 in [2, 3] only x1 + 1 vanishes
  // (at x1 = -1); x2 - 1 >= 1 there.
  const auto d = definedness_of("x2, 1/(x1*x2 - x1 + x2 - 1)", "x1 in [-2, 2], x2 in [2, 3]");
  ASSERT_EQ(d.findings.size(), 1u) << d.summary();
  EXPECT_EQ(d.findings[0].requirement, "x1+1 != 0 (a factor of a denominator)");
  EXPECT_EQ(d.conditions, 2u);
}

TEST(Definedness, PoleOutsideTheBoxIsNoFinding) {
  const auto d = definedness_of("x2, -1/x1", "x1 in [0.5, 2], x2 in [-1, 1]");
  EXPECT_TRUE(d.findings.empty()) << d.summary();
  EXPECT_EQ(d.conditions, 1u);
}

TEST(Definedness, NonDyadicZeroOfACompoundDivisorIsProvedBySignChange) {
  // 1/(3 x1 - 1 + x2^2/100) on x1 in [-1, 1], x2 in [0, 0.5]: the divisor changes sign along
  // x1 (negative at x1 = -1, positive at x1 = 1) with its zero near x1 = 1/3 - x2^2/300, in
  // [0.3325, 0.3334] for x2 in [0, 0.5].
  const auto d = definedness_of("x2, 1/(3*x1 - 1 + x2^2/100)", "x1 in [-1, 1], x2 in [0, 0.5]");
  ASSERT_EQ(d.findings.size(), 1u);
  const auto& f = d.findings[0];
  EXPECT_EQ(f.status, DefinedStatus::violated_somewhere) << f.text();
  const auto [lo, hi] = range_of(f.sub_box, "x1");
  EXPECT_LE(lo, 0.3325);
  EXPECT_GE(hi, 1.0 / 3);
  EXPECT_LT(hi - lo, 0.1) << f.sub_box;  // localised, not the whole range
}

TEST(Definedness, SqrtOfANegativeRangeIsAnErrorOnTheWholeBox) {
  const auto d = definedness_of("x2, -sqrt(x1)", "x1 in [-2, -1], x2 in [-1, 1]");
  ASSERT_EQ(d.findings.size(), 1u);
  EXPECT_EQ(d.findings[0].status, DefinedStatus::violated_everywhere);
  const auto errors = d.errors();
  ASSERT_EQ(errors.size(), 1u);
  EXPECT_EQ(errors[0].loc.line, 3);
  EXPECT_NE(errors[0].message.find("whole domain box"), std::string::npos);
}

TEST(Definedness, SqrtOnARangeStartingAtZeroIsDefined) {
  const auto d = definedness_of("x2, -sqrt(x1)", "x1 in [0, 1], x2 in [-1, 1]");
  EXPECT_TRUE(d.findings.empty()) << d.summary();
}

TEST(Definedness, RangeConditionsNameAFailingPointOfTheirOwn) {
  // x1^(1/3) needs x1 >= 0: on [-1, 1] it fails at x1 = -1 (not at 0, where it holds);
  // log(x1) needs x1 > 0: on [0, 1] it fails at x1 = 0.
  const auto root = definedness_of("x2, -x1^(1/3)", "x1 in [-1, 1], x2 in [-1, 1]");
  ASSERT_EQ(root.findings.size(), 1u);
  EXPECT_NE(root.findings[0].witness.find("fails at x1 = -1 "), std::string::npos)
      << root.findings[0].witness;
  const auto log0 = definedness_of("x2, -log(x1)", "x1 in [0, 1], x2 in [-1, 1]");
  ASSERT_EQ(log0.findings.size(), 1u);
  EXPECT_NE(log0.findings[0].witness.find("fails at x1 = 0 "), std::string::npos)
      << log0.findings[0].witness;
}

TEST(Definedness, RootsOfSquaresAreDefinedThroughZero) {
  // sqrt(x1^2) (seed 004's |x1|) and sqrt(x1^2 + x2^4) reach 0 exactly at the box's centre.
  const auto d = definedness_of("x2, -sqrt(x1^2) - sqrt(x1^2 + x2^4) + log(exp(x1) + x2^2)",
                                "x1 in [-1, 1], x2 in [-1, 1]");
  EXPECT_TRUE(d.findings.empty()) << d.summary();
  EXPECT_EQ(d.conditions, 3u);
}

TEST(Definedness, CompoundSqrtArgumentNegativeOnPartOfTheBox) {
  // sqrt(1 - x1^2 - x2^2) on [-1, 1]^2: negative at the corners (1 - 2 = -1), so it fails on a
  // sub-box; proved by an exact point (a corner or the centre of a corner sub-box).
  const auto d = definedness_of("x2, sqrt(1 - x1^2 - x2^2)", "x1 in [-1, 1], x2 in [-1, 1]");
  ASSERT_EQ(d.findings.size(), 1u);
  EXPECT_EQ(d.findings[0].status, DefinedStatus::violated_somewhere) << d.summary();
}

TEST(Definedness, LogArgumentNegativeOnASubBox) {
  // log(x2 + 1/3) needs x2 > -1/3: it fails on x2 in [-1, -1/3].
  const auto d = definedness_of("x2, log(x2 + 1/3)", "x1 in [-1, 1], x2 in [-1, 1]");
  ASSERT_EQ(d.findings.size(), 1u);
  const auto& f = d.findings[0];
  EXPECT_EQ(f.status, DefinedStatus::violated_somewhere);
  const auto [lo, hi] = range_of(f.sub_box, "x2");
  EXPECT_EQ(lo, -1);
  EXPECT_GE(hi, -1.0 / 3);
  EXPECT_LT(hi, 0);
}

TEST(Definedness, TanPoleAtHalfPiInsideTheBox) {
  // tan(x1) on [-2, 2]: cos x1 vanishes at +-pi/2 = +-1.5708.
  const auto d = definedness_of("x2, tan(x1)", "x1 in [-2, 2], x2 in [-1, 1]");
  ASSERT_EQ(d.findings.size(), 1u);
  const auto& f = d.findings[0];
  EXPECT_EQ(f.status, DefinedStatus::violated_somewhere) << f.text();
  const auto [lo, hi] = range_of(f.sub_box, "x1");
  EXPECT_LE(lo, -M_PI / 2);
  EXPECT_GE(hi, M_PI / 2);
  const auto d2 = definedness_of("x2, tan(x1)", "x1 in [-1.5, 1.5], x2 in [-1, 1]");
  EXPECT_TRUE(d2.findings.empty()) << d2.summary();
}

TEST(Definedness, OutputsAreCheckedToo) {
  const auto d = definedness_of("x2, -x1", "x1 in [-1, 1], x2 in [-1, 1]", "log(x1)");
  ASSERT_EQ(d.findings.size(), 1u);
  EXPECT_EQ(d.findings[0].component, "h1");
}

TEST(Definedness, HugeAndTinyCoefficientsAreRefusedWithTheirPlace) {
  const auto huge = definedness_of("1e300*x2, -1e300*x1^3", "x1 in [-1, 1], x2 in [-1, 1]");
  ASSERT_EQ(huge.errors().size(), 2u);
  EXPECT_EQ(huge.errors()[0].loc.line, 3);
  EXPECT_NE(huge.errors()[0].message.find("1e+300"), std::string::npos);
  const auto tiny = definedness_of("x2, -1e-200*x1", "x1 in [-1, 1], x2 in [-1, 1]");
  EXPECT_EQ(tiny.errors().size(), 1u);
  const auto fine = definedness_of("1e100*x2, -x1", "x1 in [-1, 1], x2 in [-1, 1]");
  EXPECT_TRUE(fine.errors().empty());
}

TEST(Definedness, BoxEndpointsBeyondTheLimitAreRefused) {
  EXPECT_EQ(definedness_of("x2, -x1", "x1 in [0, 1e-300], x2 in [-1, 1]").errors().size(), 1u);
  EXPECT_EQ(definedness_of("x2, -x1", "x1 in [-1e200, 1e200], x2 in [-1, 1]").errors().size(),
            3u);  // the box, and f2 = -x1 and h1 = x1 reaching 1e200
  EXPECT_TRUE(definedness_of("x2, -x1", "x1 in [0, 1e-100], x2 in [-1, 1]").errors().empty());
}

TEST(Definedness, ValuesBeyondTheLimitAreRefused) {
  // exp(400 x1) reaches e^400 = 5.2e173 at x1 = 1: each factor is fine, the value is not.
  const auto d = definedness_of("x2, -exp(400*x1)", "x1 in [-1, 1], x2 in [-1, 1]");
  ASSERT_EQ(d.errors().size(), 1u);
  EXPECT_NE(d.errors()[0].message.find("beyond 1e150"), std::string::npos);
}

}  // namespace
