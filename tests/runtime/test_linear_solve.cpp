// obsynth/linear_solve.hpp: packed symmetric blocks and the guarded solves, against values
// worked out by hand in each test.
#include "obsynth/linear_solve.hpp"

#include <gtest/gtest.h>

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

}  // namespace
