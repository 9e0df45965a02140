// The polynomial ring (synth/poly.hpp) against GiNaC: conversions, derivatives, products,
// growth classes; and the triangular shortcut of the observability stage against the
// general cofactor path.
#include <gtest/gtest.h>

#include <random>

#include "analysis/observability.hpp"
#include "foundation/budget.hpp"
#include "front/parse.hpp"
#include "support/expect.hpp"
#include "symbolic/expr_print.hpp"
#include "symbolic/lie.hpp"
#include "symbolic/poly.hpp"
#include "symbolic/symbolic.hpp"

namespace obsynth {
namespace {

using GiNaC::ex;
using GiNaC::symbol;

using obsynth::testing::derivative_along;
using obsynth::testing::same;

struct Fixture {
  symbol x1{"x1"}, x2{"x2"}, x3{"x3"}, k{"k"};
  Symbols x{x1, x2, x3};
};

// Random polynomials in x, k and the atoms sin(x1 + x2), cos(x1 + x2), exp(x3), tanh(x2^2).
ex random_expression(const Fixture& f, std::mt19937& rng) {
  const ex atoms[] = {f.x1,
                      f.x2,
                      f.x3,
                      f.k,
                      GiNaC::sin(f.x1 + f.x2),
                      GiNaC::cos(f.x1 + f.x2),
                      GiNaC::exp(f.x3),
                      GiNaC::tanh(f.x2 * f.x2)};
  std::uniform_int_distribution<int> atom(0, 7), expo(0, 3), coef(-5, 5), count(1, 6);
  ex sum = 0;
  for (int t = count(rng); t > 0; --t) {
    ex term = GiNaC::numeric(coef(rng), 1 + std::abs(coef(rng)));
    for (int a = 0; a < 3; ++a) term *= GiNaC::pow(atoms[atom(rng)], expo(rng));
    sum += term;
  }
  return sum * (1 + f.x1);  // an unexpanded product, as models are written
}

TEST(PolyRing, RoundTripDerivativeAndProductAgreeWithGinac) {
  Fixture f;
  std::mt19937 rng(7);
  for (int trial = 0; trial < 40; ++trial) {
    const ex a = random_expression(f, rng), b = random_expression(f, rng);
    const auto ring = PolyRing::for_expressions({a, b}, f.x);
    ASSERT_TRUE(ring) << a << " ; " << b;
    const auto pa = ring->from_ex(a), pb = ring->from_ex(b);
    ASSERT_TRUE(pa && pb);
    EXPECT_TRUE(same(ring->to_ex(*pa), a)) << a;
    EXPECT_TRUE(same(ring->to_ex(PolyRing::product(*pa, *pb)), a * b));
    for (std::size_t j = 0; j < 3; ++j)
      EXPECT_TRUE(same(ring->to_ex(ring->derivative(*pa, j)), a.diff(f.x[j])))
          << a << " d/d" << f.x[j];
    // The Lie derivative of a along the field (b, a, 1).
    const std::vector<Poly> field{*pb, *pa, *ring->from_ex(1)};
    std::vector<Poly> grad;
    for (std::size_t j = 0; j < 3; ++j) grad.push_back(ring->derivative(*pa, j));
    EXPECT_TRUE(same(ring->to_ex(PolyRing::dot(grad, field)), derivative_along(a, {b, a, 1}, f.x)));
  }
}

TEST(PolyRing, SinAndCosAreEachOthersCompanions) {
  Fixture f;
  // Only sin appears; its derivative needs cos, which the ring adds.
  const auto ring = PolyRing::for_expressions({GiNaC::sin(2 * f.x1) * f.x2}, f.x);
  ASSERT_TRUE(ring);
  const Poly p = *ring->from_ex(GiNaC::sin(2 * f.x1) * f.x2);
  EXPECT_TRUE(same(ring->to_ex(ring->derivative(ring->derivative(p, 0), 0)),
                   -4 * GiNaC::sin(2 * f.x1) * f.x2));
  // Nested atoms differentiate by the chain rule through the inner atom.
  const ex nested = GiNaC::sin(GiNaC::exp(f.x1) + f.x2);
  const auto r2 = PolyRing::for_expressions({nested}, f.x);
  ASSERT_TRUE(r2);
  EXPECT_TRUE(same(r2->to_ex(r2->derivative(*r2->from_ex(nested), 0)), nested.diff(f.x1)));
}

TEST(PolyRing, ExponentialsShareOneLaurentBase) {
  Fixture f;
  const ex e1 = GiNaC::exp(f.x1), e2 = GiNaC::exp(2 * f.x1), em2 = GiNaC::exp(-2 * f.x1);
  const auto ring = PolyRing::for_expressions({e2 * f.x2, em2, GiNaC::exp(-f.x1) * f.x3}, f.x);
  ASSERT_TRUE(ring);
  // exp(-2 x1) exp(2 x1) x2 is x2, exp(x1)^2 - exp(2 x1) is 0: identities of the ring.
  EXPECT_TRUE(ring->to_ex(*ring->from_ex(em2 * e2 * f.x2)).is_equal(f.x2));
  EXPECT_TRUE(ring->from_ex(GiNaC::pow(e1, 2) - e2)->is_zero());
  EXPECT_TRUE(ring->from_ex(1 / e1 - GiNaC::exp(-f.x1))->is_zero());
  // One exp per printed term, its argument expanded: exp(x1) exp(x2) -> exp(x1 + x2).
  const auto r2 = PolyRing::for_expressions({GiNaC::exp(f.x1 + f.x2), e1}, f.x);
  ASSERT_TRUE(r2);
  const ex both = r2->to_ex(*r2->from_ex(GiNaC::exp(f.x1 + f.x2) * GiNaC::exp(-f.x1)));
  EXPECT_TRUE(both.is_equal(GiNaC::exp(f.x2))) << both;
  // d/dx1 (exp(-2 x1) x2) = -2 exp(-2 x1) x2 by hand.
  const Poly p = *ring->from_ex(em2 * f.x2);
  EXPECT_TRUE(same(ring->to_ex(ring->derivative(p, 0)), -2 * em2 * f.x2));
  EXPECT_EQ(ring->growth(p), Growth::unbounded);
}

TEST(PolyRing, MultipleAnglesReduceToPowersOfOneAngle) {
  Fixture f;
  const ex s = GiNaC::sin(f.x1), c = GiNaC::cos(f.x1);
  const auto ring =
      PolyRing::for_expressions({GiNaC::sin(3 * f.x1), s, GiNaC::cos(-2 * f.x1)}, f.x);
  ASSERT_TRUE(ring);
  // sin 3a = 3 c^2 s - s^3, cos 2a = c^2 - s^2 (de Moivre, by hand).
  EXPECT_TRUE(ring->from_ex(GiNaC::sin(3 * f.x1) - (3 * c * c * s - s * s * s))->is_zero());
  EXPECT_TRUE(ring->from_ex(GiNaC::cos(2 * f.x1) - (c * c - s * s))->is_zero());
  EXPECT_TRUE(ring->from_ex(GiNaC::sin(-2 * f.x1) + 2 * s * c)->is_zero());
  // An angle that is not a multiple of the base is outside the ring.
  EXPECT_FALSE(ring->from_ex(GiNaC::sin(f.x1 / 2)));
}

TEST(PolyRing, AtomsOfLinearCombinationsDifferentiateByTheChainRule) {
  Fixture f;
  const ex arg = 2 * f.x1 + f.x2 + f.x3;
  const ex e = GiNaC::sin(arg) * GiNaC::tanh(f.x2 - f.x1) * GiNaC::exp(f.x1 - f.x3);
  const auto ring = PolyRing::for_expressions({e}, f.x);
  ASSERT_TRUE(ring);
  const Poly p = *ring->from_ex(e);
  // By hand: d/dx1 = (2 cos(arg) th + sin(arg) (th^2 - 1) + sin(arg) th) exp(x1 - x3).
  const ex th = GiNaC::tanh(f.x2 - f.x1), ex13 = GiNaC::exp(f.x1 - f.x3);
  const ex want =
      (2 * GiNaC::cos(arg) * th + GiNaC::sin(arg) * (th * th - 1) + GiNaC::sin(arg) * th) * ex13;
  EXPECT_TRUE(same(ring->to_ex(ring->derivative(p, 0)), want));
  // tanh is odd: tanh(x1 - x2) is the same atom with the opposite sign.
  EXPECT_TRUE(ring->from_ex(GiNaC::tanh(f.x1 - f.x2) + th)->is_zero());
}

TEST(CanonicalAtoms, SimplifyCombinesAndCancelsExponentials) {
  Fixture f;
  const ex x = f.x1, y = f.x2;
  EXPECT_TRUE(simplify(GiNaC::exp(-2 * x) * GiNaC::exp(2 * x) * y).is_equal(y));
  EXPECT_TRUE(simplify(y + y * GiNaC::exp(x) * GiNaC::exp(-x)).is_equal(2 * y));
  EXPECT_TRUE(
      simplify(GiNaC::pow(GiNaC::exp(x), 2) * GiNaC::exp(y)).is_equal(GiNaC::exp(2 * x + y)));
  // Across a fraction: (exp(x) + 1)/exp(-x) = exp(2x) + exp(x); a parameter in the exponent.
  EXPECT_TRUE(
      simplify((GiNaC::exp(x) + 1) / GiNaC::exp(-x)).is_equal(GiNaC::exp(2 * x) + GiNaC::exp(x)));
  EXPECT_TRUE(simplify(GiNaC::exp(f.k * x) * GiNaC::exp(-f.k * x) / (1 + x)).is_equal(1 / (1 + x)));
  // Outside the ring (atan) the exp factors still cancel.
  EXPECT_TRUE(simplify(GiNaC::atan(x) * GiNaC::exp(x) * GiNaC::exp(-x)).is_equal(GiNaC::atan(x)));
  // Multiple angles: sin(2x) cos(x) + sin(x) = 2 cos(x)^2 sin(x) + sin(x).
  const ex s = GiNaC::sin(x), c = GiNaC::cos(x);
  EXPECT_TRUE(GiNaC::expand(simplify(GiNaC::sin(2 * x) * c + s) - (2 * c * c * s + s)).is_zero());
  // ... also outside the ring: over a denominator, and next to atan.
  const ex double_angle = GiNaC::sin(2 * x) - 2 * s * c;
  EXPECT_TRUE(simplify(double_angle / (1 + x * x)).is_zero());
  EXPECT_TRUE(
      simplify(GiNaC::atan(y) * double_angle + GiNaC::cos(-2 * x) - c * c + s * s).is_zero());
}

TEST(CanonicalAtoms, PrintedProductsCarryOneExp) {
  Fixture f;
  const ex x = f.x1, y = f.x2;
  EXPECT_EQ(to_string(GiNaC::exp(-2 * x) * GiNaC::exp(2 * x) * y), "x2");
  EXPECT_EQ(to_string(y / GiNaC::exp(x)), "exp(-x1)*x2");
  EXPECT_EQ(to_string(GiNaC::pow(GiNaC::exp(x), 3)), "exp(3*x1)");
  EXPECT_EQ(to_string(GiNaC::exp(x) * GiNaC::exp(y) * f.k), "exp(x1+x2)*k");
}

TEST(PolyRing, ExpressionsOutsideTheRingAreDeclined) {
  Fixture f;
  const std::vector<ex> outside{1 / (1 + f.x1),       GiNaC::sqrt(f.x1),
                                GiNaC::log(f.x1),     GiNaC::atan(f.x1),
                                GiNaC::tan(f.x1),     GiNaC::pow(f.x1, GiNaC::numeric(3, 2)),
                                GiNaC::pow(f.x1, 300)};
  for (const ex& e : outside) EXPECT_FALSE(PolyRing::for_expressions({e}, f.x)) << e;
}

TEST(PolyRing, ExponentOverflowIsReportedNotWrapped) {
  Fixture f;
  const ex e = GiNaC::pow(f.x1, 100);  // exponents are signed 8-bit: 200 is out of range
  const auto ring = PolyRing::for_expressions({e}, f.x);
  ASSERT_TRUE(ring);
  const Poly p = *ring->from_ex(e);
  EXPECT_THROW(PolyRing::product(p, p), PolyOverflow);
}

TEST(PolyRing, GrowthClasses) {
  Fixture f;
  const ex c = 3 * f.k * GiNaC::sin(f.k), b = GiNaC::sin(f.x1) * GiNaC::tanh(f.x2) + f.k,
           u = f.x1 * GiNaC::cos(f.x2), e = GiNaC::exp(f.x3);
  const auto ring = PolyRing::for_expressions({c, b, u, e}, f.x);
  ASSERT_TRUE(ring);
  EXPECT_EQ(ring->growth(*ring->from_ex(c)), Growth::constant);
  EXPECT_EQ(ring->growth(*ring->from_ex(b)), Growth::bounded);
  EXPECT_EQ(ring->growth(*ring->from_ex(u)), Growth::unbounded);
  EXPECT_EQ(ring->growth(*ring->from_ex(e)), Growth::unbounded);
}

TEST(PolyRing, EvaluationMatchesGinac) {
  Fixture f;
  std::mt19937 rng(11);
  for (int trial = 0; trial < 10; ++trial) {
    const ex a = random_expression(f, rng);
    const auto ring = PolyRing::for_expressions({a}, f.x);
    ASSERT_TRUE(ring);
    GiNaC::exmap pt{{f.x1, GiNaC::numeric(1, 3)},
                    {f.x2, GiNaC::numeric(-2, 7)},
                    {f.x3, GiNaC::numeric(5, 11)},
                    {f.k, GiNaC::numeric(3, 2)}};
    const auto values = ring->values_at(pt, 40);
    ASSERT_TRUE(values);
    const long saved = GiNaC::Digits;
    GiNaC::Digits = 40;
    const GiNaC::numeric got = PolyRing::evaluate(*ring->from_ex(a), *values);
    const GiNaC::numeric want = GiNaC::ex_to<GiNaC::numeric>(GiNaC::evalf(a.subs(pt)));
    GiNaC::Digits = saved;
    EXPECT_LT(GiNaC::abs(got - want).to_double(), 1e-30 * (1 + GiNaC::abs(want).to_double())) << a;
  }
}

TEST(Triangular, ColumnsFoundUpToPermutation) {
  Fixture f;
  // Row k nonzero only in columns {2, 0, 1}[0..k].
  const ExMatrix a{{0, 0, f.x1}, {f.x2, 0, 1}, {3, f.x1 * f.x2, f.x3}};
  const auto cols = triangular_columns(a);
  ASSERT_TRUE(cols);
  EXPECT_EQ(*cols, (std::vector<std::size_t>{2, 0, 1}));
  EXPECT_FALSE(triangular_columns(ExMatrix{{1, f.x1}, {f.x2, 1}}));  // full 2x2
  EXPECT_FALSE(triangular_columns(ExMatrix{{0, 0}, {1, 1}}));        // zero row
}

// A model whose O is triangular only after permuting columns: the shortcut's det, r (via the
// cofactors) and rank-drop set against an independent computation with GiNaC's determinant.
TEST(Triangular, ShortcutAgreesWithCofactorExpansion) {
  const std::string src =
      "model perm\nstates x1 x2 x3\n"
      "f = [x1*x3, x1 + x2^2, x2]\n"  // y = x3: L_f y = x2, L_f^2 y = x1 + x2^2
      "h = x3\n";
  const Model m = parse_model(src, "perm.sym");
  Budget budget;
  const Observability ob = analyse_observability(m, budget);
  ASSERT_TRUE(ob.triangular);
  EXPECT_EQ(ob.diag_columns, (std::vector<std::size_t>{2, 1, 0}));
  EXPECT_EQ(ob.generic_rank, 3u);
  GiNaC::matrix O(3, 3);
  for (unsigned i = 0; i < 3; ++i)
    for (unsigned j = 0; j < 3; ++j) O(i, j) = ob.O[i][j];
  EXPECT_TRUE(same(ob.det, O.determinant())) << ob.det << " vs " << O.determinant();
  // O (cofactors / det) = e_3.
  for (unsigned i = 0; i < 3; ++i) {
    ex acc = 0;
    for (unsigned j = 0; j < 3; ++j) acc += O(i, j) * ob.last_row_cofactors[j];
    EXPECT_TRUE(same(GiNaC::normal(acc / ob.det), i == 2 ? 1 : 0)) << i;
  }
}

TEST(Triangular, VanishingDiagonalFallsBackToTheGeneralPath) {
  // L_f y = x2 - x2 = 0 structurally after simplification would make O singular; use a
  // diagonal that vanishes only as sin^2 + cos^2 - 1 (not structurally zero).
  const std::string src =
      "model sing\nstates x1 x2\n"
      "f = [x2, (sin(x1)^2 + cos(x1)^2 - 1)*x2]\n"
      "h = x1\n";
  const Model m = parse_model(src, "sing.sym");
  Budget budget;
  const Observability ob = analyse_observability(m, budget);
  EXPECT_EQ(ob.generic_rank, 2u);  // O = [[1, 0], [0, 1]]: triangular, regular
  const std::string src2 =
      "model sing2\nstates x1 x2\n"
      "f = [(sin(x2)^2 + cos(x2)^2 - 1)*x2, 0]\n"
      "h = x1\n";
  const Observability ob2 = analyse_observability(parse_model(src2, "sing2.sym"), budget);
  EXPECT_EQ(ob2.generic_rank, 1u) << "a diagonal entry that is zero only up to sin^2 + cos^2 = 1";
}

}  // namespace
}  // namespace obsynth
