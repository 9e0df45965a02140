// obsynth/linear_solve.hpp: packed symmetric blocks and the guarded solves, against values
// worked out by hand in each test.
#include "obsynth/linear_solve.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace {

template <class S>
class LinearSolve : public ::testing::Test {};
using Scalars = ::testing::Types<float, double>;
TYPED_TEST_SUITE(LinearSolve, Scalars);

TYPED_TEST(LinearSolve, UnpacksTheUpperTriangleRowByRow) {
  using S = TypeParam;
  Eigen::Matrix<S, 8, 1> w;
  w << 9, 9, 1, 2, 3, 4, 5, 6;  // block at offset 2: [[1,2,3],[2,4,5],[3,5,6]]
  Eigen::Matrix<S, 3, 3> M;
  obsynth::unpack_symmetric<2, 3>(w, M);
  Eigen::Matrix<S, 3, 3> expected;
  expected << 1, 2, 3, 2, 4, 5, 3, 5, 6;
  EXPECT_EQ(M, expected);
}

TYPED_TEST(LinearSolve, PositiveDefinitenessOfPackedBlocks) {
  using S = TypeParam;
  Eigen::Matrix<S, 3, 1> spd, indefinite, semidefinite;
  spd << 2, 1, 2;           // eigenvalues 1, 3
  indefinite << 1, 2, 1;    // eigenvalues -1, 3
  semidefinite << 1, 1, 1;  // eigenvalues 0, 2
  EXPECT_TRUE((obsynth::packed_positive_definite<0, 2>(spd)));
  EXPECT_FALSE((obsynth::packed_positive_definite<0, 2>(indefinite)));
  EXPECT_FALSE((obsynth::packed_positive_definite<0, 2>(semidefinite)));
  Eigen::Matrix<S, 3, 1> nan = spd;
  nan(1) = std::numeric_limits<S>::quiet_NaN();
  EXPECT_FALSE((obsynth::packed_positive_definite<0, 2>(nan)));
}

TYPED_TEST(LinearSolve, CholeskySolveMatchesTheHandSolution) {
  using S = TypeParam;
  Eigen::Matrix<S, 2, 2> M;
  M << 2, 1, 1, 2;  // inverse (1/3) [[2,-1],[-1,2]]
  Eigen::Matrix<S, 2, 1> v(S(3), S(0)), x;
  ASSERT_TRUE((obsynth::solve_cholesky<S, 2>(M, v, x)));
  EXPECT_NEAR(double(x(0)), 2.0, 1e-6);
  EXPECT_NEAR(double(x(1)), -1.0, 1e-6);
  M << 1, 2, 2, 1;  // indefinite
  EXPECT_FALSE((obsynth::solve_cholesky<S, 2>(M, v, x)));
}

TYPED_TEST(LinearSolve, LuSolvePivotsAndRefusesSingularMatrices) {
  using S = TypeParam;
  Eigen::Matrix<S, 2, 2> M;
  M << 0, 1, 1, 0;  // needs a row exchange
  Eigen::Matrix<S, 2, 1> v(S(5), S(7)), x;
  ASSERT_TRUE((obsynth::solve_lu<S, 2>(M, v, x)));
  EXPECT_NEAR(double(x(0)), 7.0, 1e-6);
  EXPECT_NEAR(double(x(1)), 5.0, 1e-6);
  M << 1, 2, 2, 4;  // rank 1
  EXPECT_FALSE((obsynth::solve_lu<S, 2>(M, v, x)));
  M << 1, 0, 0, 0;
  EXPECT_FALSE((obsynth::solve_lu<S, 2>(M, v, x)));
}

// The ill-conditioning limit: a pivot ratio at most sqrt(epsilon) is refused, whatever the
// determinant. diag(1, r) has pivots 1 and r (no exchange) and the solution (v0, v1 / r); the
// upper triangular [[r, 1], [0, 1]] needs no exchange either and has pivots r and 1. Both are
// exactly invertible, far from D * epsilon, and refused below sqrt(epsilon) only.
TYPED_TEST(LinearSolve, LuSolveRefusesIllConditionedMatrices) {
  using S = TypeParam;
  const S root_eps = std::sqrt(std::numeric_limits<S>::epsilon());
  // 2^-26 in double; float: sqrt(2^-23) = 3.4526698e-4.
  EXPECT_EQ(obsynth::lu_conditioning_limit<S>(), root_eps);
  Eigen::Matrix<S, 2, 2> M;
  Eigen::Matrix<S, 2, 1> v(S(3), S(1)), x;
  const S above = 2 * root_eps, below = root_eps / 2;
  M << 1, 0, 0, above;
  ASSERT_TRUE((obsynth::solve_lu<S, 2>(M, v, x)));
  EXPECT_EQ(x(0), S(3));
  EXPECT_NEAR(double(x(1) * above), 1.0, 1e-6);
  M << 1, 0, 0, below;
  EXPECT_FALSE((obsynth::solve_lu<S, 2>(M, v, x)));
  M << 1, 0, 0, root_eps;  // at the limit: refused (the rule is pivot > limit * largest)
  EXPECT_FALSE((obsynth::solve_lu<S, 2>(M, v, x)));
  M << below, 1, 0, 1;
  EXPECT_FALSE((obsynth::solve_lu<S, 2>(M, v, x)));
  // A uniformly small matrix is not ill-conditioned: only the ratio counts.
  M << below, 0, 0, below;
  ASSERT_TRUE((obsynth::solve_lu<S, 2>(M, v, x)));
  EXPECT_NEAR(double(x(0) * below), 3.0, 1e-5);
}

}  // namespace
