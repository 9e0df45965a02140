// Rigorous enclosures (synth/certify/enclosure.hpp) against independent oracles: maxima known
// by hand, exact maxima of separable polynomials, and dense sampling in plain double arithmetic
// (never through the library's own evaluator).
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <array>
#include <cmath>
#include <random>

#include "certify/enclosure.hpp"

using namespace obsynth::certify;
using GiNaC::ex;

namespace {

GiNaC::symbol x("x"), y("y"), z("z");

Box box1(const GiNaC::symbol& s, double lo, double hi) {
  return Box{{s}, {{lo, hi}}};
}

TEST(Enclosure, SinPlusSquareOnMinus2To2) {
  // |sin x + x^2| on [-2, 2]: the function increases on [-0.45, 2] and is 3.09 at x = -2, so the
  // supremum is sin(2) + 4 at x = 2.
  const double truth = std::sin(2.0) + 4.0;
  const Bound b = sup_abs(sin(x) + pow(x, 2), box1(x, -2, 2));
  EXPECT_EQ(b.kind, BoundKind::rigorous) << b.method;
  EXPECT_STREQ(bound_kind_name(b.kind), "rigorous");
  EXPECT_GE(b.value, truth);
  EXPECT_LE(b.value, truth * 1.05 + 1e-12);
  ASSERT_EQ(b.worst_point.size(), 1u);
  EXPECT_NEAR(b.worst_point[0], 2.0, 0.1);
}

TEST(Enclosure, ProductOfTwoVariables) {
  // |x y| on [-1, 3] x [-2, 1]: corner products 2, -1, -6, 3 -> 6 at (3, -2).
  const Bound b = sup_abs(x * y, Box{{x, y}, {{-1, 3}, {-2, 1}}});
  EXPECT_EQ(b.kind, BoundKind::rigorous);
  EXPECT_GE(b.value, 6.0);
  EXPECT_LE(b.value, 6.0 * 1.05);
  ASSERT_EQ(b.worst_point.size(), 2u);
  EXPECT_DOUBLE_EQ(b.worst_point[0], 3.0);
  EXPECT_DOUBLE_EQ(b.worst_point[1], -2.0);
}

TEST(Enclosure, LipschitzOfTanhIsOne) {
  // d/dx tanh = 1 - tanh^2 <= 1, equality at 0.
  const Bound b = lipschitz_bound({tanh(x)}, {x}, box1(x, -3, 3));
  EXPECT_EQ(b.kind, BoundKind::rigorous);
  EXPECT_GE(b.value, 1.0);
  EXPECT_LE(b.value, 1.05);
}

TEST(Enclosure, LipschitzOfARotationField) {
  // phi = (x cos z - y sin z, x sin z + y cos z): D_(x,y) phi is a rotation, norm 1 for every z.
  const Bound b = lipschitz_bound({x * cos(z) - y * sin(z), x * sin(z) + y * cos(z)}, {x, y},
                                  Box{{x, y, z}, {{-1, 1}, {-1, 1}, {-3, 3}}});
  EXPECT_EQ(b.kind, BoundKind::rigorous) << b.method;
  EXPECT_GE(b.value, 1.0);
  EXPECT_LE(b.value, 1.05);
}

TEST(Enclosure, ElementaryFunctions) {
  // sqrt: increasing, 2 at 4; log: |log| is log 3 = 1.0986 at 3 (|log 1/2| = 0.69);
  // atan on [-5, 1]: |atan(-5)| = 1.3734; exp(-x^2) <= 1 at 0; |x|^(3/2) on [-1, 4] -> 8.
  struct Case {
    ex e;
    double lo, hi, truth;
  } cases[] = {
      {sqrt(x), 0, 4, 2.0},
      {log(x), 0.5, 3, std::log(3.0)},
      {atan(x), -5, 1, std::atan(5.0)},
      {exp(-pow(x, 2)), -1, 2, 1.0},
      {pow(abs(x), GiNaC::numeric(3, 2)), -1, 4, 8.0},
      {cos(x) * x, 0, 0.5, 0.5 * std::cos(0.5)},
      {1 / (1 + pow(x, 2)), -2, 3, 1.0},
  };
  for (const auto& c : cases) {
    const Bound b = sup_abs(c.e, box1(x, c.lo, c.hi));
    EXPECT_EQ(b.kind, BoundKind::rigorous) << c.e << ": " << b.method;
    EXPECT_GE(b.value, c.truth) << c.e;
    EXPECT_LE(b.value, c.truth * 1.05 + 1e-12) << c.e;
  }
}

TEST(Enclosure, PoleFallsBackToSampledAndSaysSo) {
  // 1/x on [-1, 1] is unbounded: no rigorous bound exists.
  const Bound b = sup_abs(1 / x, box1(x, -1, 1));
  EXPECT_EQ(b.kind, BoundKind::sampled);
  EXPECT_NE(b.method.find("sampled"), std::string::npos);
  // An unsupported function: sampled, named.
  const Bound c = sup_abs(asin(x), box1(x, -0.5, 0.5));
  EXPECT_EQ(c.kind, BoundKind::sampled);
  EXPECT_NE(c.method.find("asin"), std::string::npos) << c.method;
  EXPECT_NEAR(c.value, std::asin(0.5), 1e-9);  // the corners are sampled
}

TEST(Enclosure, UnknownSymbolIsAnError) {
  EXPECT_THROW(sup_abs(x + y, box1(x, 0, 1)), std::invalid_argument);
}

// Exact maxima: p = prod_k (a_k x_k^2 + b_k x_k + c_k); max |p| over a box is the product of
// max |quadratic| over the intervals, each at an endpoint or at the vertex -b/(2a).
double max_abs_quadratic(double a, double b, double c, double lo, double hi) {
  auto q = [&](double t) { return std::fabs((a * t + b) * t + c); };
  double m = std::max(q(lo), q(hi));
  if (a != 0) {
    const double v = -b / (2 * a);
    if (v > lo && v < hi) m = std::max(m, q(v));
  }
  return m;
}

TEST(Enclosure, RandomSeparablePolynomialsExactMaxima) {
  std::mt19937 rng(12345);
  std::uniform_int_distribution<int> coef(-5, 5), end(-4, 4);
  const GiNaC::symbol* vars[] = {&x, &y, &z};
  for (int trial = 0; trial < 40; ++trial) {
    const int d = 1 + trial % 3;
    Box box;
    ex p = 1;
    double truth = 1;
    for (int k = 0; k < d; ++k) {
      const int a = coef(rng), b = coef(rng), c = coef(rng);
      int lo = end(rng), hi = end(rng);
      if (lo > hi) std::swap(lo, hi);
      if (lo == hi) ++hi;
      box.vars.push_back(*vars[k]);
      box.ranges.push_back({double(lo), double(hi)});
      p *= a * pow(*vars[k], 2) + b * *vars[k] + c;
      truth *= max_abs_quadratic(a, b, c, lo, hi);
    }
    p = p.expand();  // the enclosure sees the expanded (dependency-heavy) form
    const Bound r = sup_abs(p, box);
    ASSERT_EQ(r.kind, BoundKind::rigorous) << p;
    EXPECT_GE(r.value, truth * (1 - 1e-14)) << p;
    EXPECT_LE(r.value, truth * 1.05 + 1e-9) << p;
  }
}

TEST(Enclosure, RandomPolynomialsNeverBelowDenseSampling) {
  std::mt19937 rng(777);
  std::uniform_int_distribution<int> coef(-9, 9), deg(0, 4);
  for (int trial = 0; trial < 30; ++trial) {
    struct Term {
      int c, i, j;
    };
    std::vector<Term> terms;
    ex p = 0;
    for (int t = 0; t < 6; ++t) {
      Term tm{coef(rng), deg(rng), deg(rng)};
      terms.push_back(tm);
      p += tm.c * pow(x, tm.i) * pow(y, tm.j);
    }
    const Box box{{x, y}, {{-1.5, 1}, {-0.5, 2}}};
    const Bound r = sup_abs(p, box, {256, 0.05});
    ASSERT_EQ(r.kind, BoundKind::rigorous);
    double dense = 0;
    for (int a = 0; a <= 200; ++a)
      for (int b = 0; b <= 200; ++b) {
        const double xv = -1.5 + 2.5 * a / 200, yv = -0.5 + 2.5 * b / 200;
        double v = 0;
        for (const auto& tm : terms) v += tm.c * std::pow(xv, tm.i) * std::pow(yv, tm.j);
        dense = std::max(dense, std::fabs(v));
      }
    EXPECT_GE(r.value, dense) << p;
    // The sampled bound is a lower estimate, never above the dense maximum by more than rounding.
    const Bound s = sup_abs_sampled(p, box, 512);
    EXPECT_EQ(s.kind, BoundKind::sampled);
    EXPECT_LE(s.value, r.value);
  }
}

TEST(Enclosure, MatrixNorm) {
  // [[x, 1], [1, -x]] has eigenvalues +-sqrt(x^2 + 1): norm sqrt(5) at x = 2.
  GiNaC::matrix M = {{x, 1}, {1, -x}};
  const Bound b = matrix_norm_bound(M, box1(x, -1, 2));
  EXPECT_EQ(b.kind, BoundKind::rigorous);
  EXPECT_GE(b.value, std::sqrt(5.0));
  EXPECT_LE(b.value, std::sqrt(5.0) * 1.05);
  // A constant matrix with mixed signs: ||[[1, 1], [1, -1]]|| = sqrt 2, where the norm of the
  // entrywise absolute value would give 2.
  GiNaC::matrix C = {{1, 1}, {1, -1}};
  const Bound c = matrix_norm_bound(C, box1(x, 0, 1));
  EXPECT_GE(c.value, std::sqrt(2.0));
  EXPECT_LE(c.value, std::sqrt(2.0) * (1 + 1e-9));
}

TEST(Enclosure, NegativeDefiniteProven) {
  // S = [[-2 - x^2, x], [x, -1]]: trace -3 - x^2 < 0, det 2 > 0, lambda_max(x) =
  // (tr + sqrt(tr^2 - 8)) / 2, largest at x = +-1: (-4 + sqrt 8) / 2 = -0.5858.
  GiNaC::matrix S = {{-2 - pow(x, 2), x}, {x, -1}};
  const DefinitenessVerdict v = negative_definite(S, box1(x, -1, 1));
  EXPECT_TRUE(v.holds);
  EXPECT_EQ(v.kind, BoundKind::rigorous) << v.method;
  EXPECT_GE(v.max_eigenvalue_bound, (-4 + std::sqrt(8.0)) / 2);
  EXPECT_LT(v.max_eigenvalue_bound, 0);
}

TEST(Enclosure, NegativeDefiniteFailsWithWorstPoint) {
  // [[-1, x], [x, -1]] has eigenvalues -1 +- x: not negative definite for x >= 1.
  GiNaC::matrix S = {{-1, x}, {x, -1}};
  const DefinitenessVerdict v = negative_definite(S, box1(x, 0, 2));
  EXPECT_FALSE(v.holds);
  EXPECT_EQ(v.kind, BoundKind::rigorous) << v.method;
  ASSERT_EQ(v.worst_point.size(), 1u);
  EXPECT_GE(v.worst_point[0], 1.0);
  EXPECT_GE(v.max_eigenvalue_bound, 1.0);  // an upper bound of lambda_max = 1 at x = 2
  // Non-symmetric input is symmetrized: eta' S eta only sees (S + S')/2.
  GiNaC::matrix N = {{-1, 4}, {-4, -1}};
  EXPECT_TRUE(negative_definite(N, box1(x, 0, 1)).holds);
}

// Random polynomial entries in (x, y) on a box, evaluated independently in plain doubles.
struct RandomPoly {
  std::vector<std::array<int, 3>> terms;  // c x^i y^j
  ex to_ex() const {
    ex e = 0;
    for (const auto& t : terms) e += t[0] * pow(x, t[1]) * pow(y, t[2]);
    return e;
  }
  double at(double xv, double yv) const {
    double v = 0;
    for (const auto& t : terms) v += t[0] * std::pow(xv, t[1]) * std::pow(yv, t[2]);
    return v;
  }
};

RandomPoly random_poly(std::mt19937& rng) {
  std::uniform_int_distribution<int> coef(-4, 4), deg(0, 2), count(1, 3);
  RandomPoly p;
  const int k = count(rng);
  for (int t = 0; t < k; ++t) p.terms.push_back({coef(rng), deg(rng), deg(rng)});
  return p;
}

TEST(Enclosure, RandomMatrixNormsNeverBelowDenseSampling) {
  std::mt19937 rng(4242);
  const Box box{{x, y}, {{-1, 1.5}, {-0.5, 1}}};
  for (int trial = 0; trial < 15; ++trial) {
    RandomPoly e[2][3];
    GiNaC::matrix M(2, 3);
    for (unsigned i = 0; i < 2; ++i)
      for (unsigned j = 0; j < 3; ++j) {
        e[i][j] = random_poly(rng);
        M(i, j) = e[i][j].to_ex();
      }
    const Bound b = matrix_norm_bound(M, box);
    ASSERT_EQ(b.kind, BoundKind::rigorous);
    double dense = 0;
    for (int a = 0; a <= 100; ++a)
      for (int c = 0; c <= 100; ++c) {
        const double xv = -1 + 2.5 * a / 100, yv = -0.5 + 1.5 * c / 100;
        Eigen::Matrix<double, 2, 3> A;
        for (int i = 0; i < 2; ++i)
          for (int j = 0; j < 3; ++j) A(i, j) = e[i][j].at(xv, yv);
        dense = std::max(dense, Eigen::JacobiSVD<Eigen::MatrixXd>(A).singularValues()(0));
      }
    EXPECT_GE(b.value, dense) << M;
    EXPECT_LE(b.value, 1.1 * dense + 1e-9) << M;
  }
}

TEST(Enclosure, RandomSymmetricMatricesEigenvalueBoundsNeverBelowDenseSampling) {
  std::mt19937 rng(99);
  const Box box{{x, y}, {{-1, 1}, {0, 1}}};
  int proven = 0, refuted = 0;
  for (int trial = 0; trial < 24; ++trial) {
    RandomPoly e[3][3];
    GiNaC::matrix S(3, 3);
    const double shift = 4.0 * (trial % 6);  // S - shift I: some definite, some not
    for (unsigned i = 0; i < 3; ++i)
      for (unsigned j = i; j < 3; ++j) {
        e[i][j] = random_poly(rng);
        e[j][i] = e[i][j];
        S(i, j) = S(j, i) = e[i][j].to_ex();
      }
    for (unsigned i = 0; i < 3; ++i) S(i, i) = e[i][i].to_ex() - GiNaC::numeric(4 * (trial % 6));
    const DefinitenessVerdict v = negative_definite(S, box);
    double dense = -1e300;
    for (int a = 0; a <= 60; ++a)
      for (int c = 0; c <= 60; ++c) {
        const double xv = -1 + 2.0 * a / 60, yv = 1.0 * c / 60;
        Eigen::Matrix3d A;
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j) A(i, j) = e[i][j].at(xv, yv) - (i == j ? shift : 0.0);
        dense = std::max(
            dense, Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(A).eigenvalues().maxCoeff());
      }
    if (v.kind != BoundKind::rigorous) continue;
    EXPECT_GE(v.max_eigenvalue_bound, dense) << S;
    if (v.holds) {
      ++proven;
      EXPECT_LT(dense, 0) << S;
    } else {
      ++refuted;
      ASSERT_EQ(v.worst_point.size(), 2u);
      Eigen::Matrix3d A;
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
          A(i, j) = e[i][j].at(v.worst_point[0], v.worst_point[1]) - (i == j ? shift : 0.0);
      EXPECT_GE(Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(A).eigenvalues().maxCoeff(), -1e-12)
          << S;
    }
  }
  EXPECT_GT(proven, 3);
  EXPECT_GT(refuted, 3);
}

}  // namespace
