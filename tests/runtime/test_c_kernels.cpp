// The C99 kernels of runtime/obsynth/c/kernels.h (generated C sources include them; the
// simulator compiles them for double), compiled here as C++ for double and float and checked
// against Eigen's own factorisations and matrix exponential (independent implementations),
// and against the C++ runtime's discretise_linear.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include <Eigen/Dense>
#include <unsupported/Eigen/MatrixFunctions>

#include "obsynth/c_kernels.hpp"
#include "obsynth/discretise.hpp"

namespace kd = obsynth::c_double;
namespace kf = obsynth::c_float;

namespace {

using Mat = Eigen::MatrixXd;

// Row-major copy of an Eigen matrix, and back.
std::vector<double> rows(const Mat& M) {
  std::vector<double> v(static_cast<std::size_t>(M.size()));
  for (Eigen::Index r = 0; r < M.rows(); ++r)
    for (Eigen::Index c = 0; c < M.cols(); ++c)
      v[static_cast<std::size_t>(r * M.cols() + c)] = M(r, c);
  return v;
}
Mat matrix(const std::vector<double>& v, Eigen::Index n) {
  Mat M(n, n);
  for (Eigen::Index r = 0; r < n; ++r)
    for (Eigen::Index c = 0; c < n; ++c) M(r, c) = v[static_cast<std::size_t>(r * n + c)];
  return M;
}

// A companion-like closed loop with poles spread over two decades, as the designs build.
Mat closed_loop(int n, double scale) {
  Mat A = Mat::Zero(n, n);
  for (int i = 1; i < n; ++i) A(i, i - 1) = 1;
  for (int i = 0; i < n; ++i) A(i, n - 1) = -scale * (i + 1.5);
  return A;
}

// exp([[A, I], [0, 0]] dt) (Eigen's Pade approximant): Phi top left, Gamma top right.
Mat augmented_exponential(const Mat& A, double dt) {
  const Eigen::Index n = A.rows();
  Mat M = Mat::Zero(2 * n, 2 * n);
  M.topLeftCorner(n, n) = A * dt;
  M.topRightCorner(n, n) = Mat::Identity(n, n) * dt;
  return M.exp();
}

TEST(CKernels, DiscretiseMatchesTheMatrixExponential) {
  for (int n : {1, 2, 4, 7})
    for (double dt : {1e-4, 1e-2, 0.5, 3.0}) {
      const Mat A = closed_loop(n, 2.0);
      const Mat X = augmented_exponential(A, dt);
      std::vector<double> E(static_cast<std::size_t>(n * n)), G(E.size()), work(4 * E.size());
      ASSERT_TRUE(kd::obsynth_discretise(rows(A).data(), n, dt, E.data(), G.data(), work.data()));
      const Mat Phi = matrix(E, n) + Mat::Identity(n, n), Gamma = matrix(G, n);
      EXPECT_LE((Phi - X.topLeftCorner(n, n)).norm(), 1e-12 * (1 + X.norm()))
          << "n = " << n << ", dt = " << dt;
      EXPECT_LE((Gamma - X.topRightCorner(n, n)).norm(), 1e-12 * (1 + X.norm()))
          << "n = " << n << ", dt = " << dt;
    }
}

// The C++ runtime hands the kernel Eigen's column-major storage (A^T read row-major) and reads
// E^T, Gamma^T back as column-major: the transposed computation (its scaling may differ: the
// 1-norm of A^T is A's infinity norm) agrees to rounding.
TEST(CKernels, DiscretiseAgreesWithTheCxxRuntime) {
  constexpr int n = 4;
  const Mat A = closed_loop(n, 3.0);
  const Eigen::Matrix<double, n, n> Af = A;
  Eigen::Matrix<double, n, n> Ec, Gc;
  ASSERT_TRUE((obsynth::discretise_linear<double, n>(Af, 0.01, Ec, Gc)));
  std::vector<double> E(n * n), G(n * n), work(4 * n * n);
  ASSERT_TRUE(kd::obsynth_discretise(rows(A).data(), n, 0.01, E.data(), G.data(), work.data()));
  EXPECT_LE((matrix(E, n) - Mat(Ec)).norm(), 1e-13 * (1 + Ec.norm()));
  EXPECT_LE((matrix(G, n) - Mat(Gc)).norm(), 1e-13 * (1 + Gc.norm()));
  // float: the same series in single precision, within float's rounding of the double result
  std::vector<float> Af32(n * n), E32(n * n), G32(n * n), w32(4 * n * n);
  for (std::size_t i = 0; i < Af32.size(); ++i) Af32[i] = static_cast<float>(rows(A)[i]);
  ASSERT_TRUE(kf::obsynth_discretise(Af32.data(), n, 0.01f, E32.data(), G32.data(), w32.data()));
  for (std::size_t i = 0; i < E.size(); ++i) {
    EXPECT_NEAR(E32[i], E[i], 1e-5 * (1 + std::abs(E[i])));
    EXPECT_NEAR(G32[i], G[i], 1e-7 + 1e-5 * std::abs(G[i]));
  }
}

TEST(CKernels, DiscretiseRefusesABadStep) {
  const std::vector<double> A{-1.0};
  std::vector<double> E(1), G(1), work(4);
  EXPECT_FALSE(kd::obsynth_discretise(A.data(), 1, 0.0, E.data(), G.data(), work.data()));
  EXPECT_FALSE(kd::obsynth_discretise(A.data(), 1, -1.0, E.data(), G.data(), work.data()));
  EXPECT_FALSE(kd::obsynth_discretise(A.data(), 1, NAN, E.data(), G.data(), work.data()));
  const std::vector<double> huge{1e300};
  EXPECT_FALSE(kd::obsynth_discretise(huge.data(), 1, 1.0, E.data(), G.data(), work.data()));
}

TEST(CKernels, SolvesMatchEigenAndRefuseWhatTheyMust) {
  std::mt19937 gen(20261205);
  std::uniform_real_distribution<double> U(-1, 1);
  for (int d : {1, 2, 3, 5}) {
    Mat B(d, d);
    for (Eigen::Index i = 0; i < B.size(); ++i) B(i) = U(gen);
    const Mat S = B * B.transpose() + Mat::Identity(d, d);  // positive definite
    Eigen::VectorXd v(d);
    for (int i = 0; i < d; ++i) v(i) = U(gen);
    std::vector<double> M = rows(S), x(static_cast<std::size_t>(d));
    ASSERT_TRUE(kd::obsynth_solve_cholesky(M.data(), d, v.data(), x.data()));
    const Eigen::VectorXd xe = S.llt().solve(v);
    for (int i = 0; i < d; ++i) EXPECT_NEAR(x[static_cast<std::size_t>(i)], xe(i), 1e-12);
    M = rows(B + 2 * Mat::Identity(d, d));
    ASSERT_TRUE(kd::obsynth_solve_lu(M.data(), d, v.data(), x.data()));
    const Eigen::VectorXd xl = (B + 2 * Mat::Identity(d, d)).partialPivLu().solve(v);
    for (int i = 0; i < d; ++i) EXPECT_NEAR(x[static_cast<std::size_t>(i)], xl(i), 1e-12);
  }
  // indefinite: no Cholesky factor; nearly singular: LU refuses (pivot ratio 1e-10 < sqrt(eps))
  std::vector<double> indefinite{1, 2, 2, 1}, x(2), v{1, 1};
  EXPECT_FALSE(kd::obsynth_solve_cholesky(indefinite.data(), 2, v.data(), x.data()));
  std::vector<double> near_singular{1, 0, 0, 1e-10};
  EXPECT_FALSE(kd::obsynth_solve_lu(near_singular.data(), 2, v.data(), x.data()));
  std::vector<double> conditioned{1, 0, 0, 1e-6};  // ratio 1e-6 > sqrt(eps) = 1.5e-8: solved
  EXPECT_TRUE(kd::obsynth_solve_lu(conditioned.data(), 2, v.data(), x.data()));
  EXPECT_NEAR(x[1], 1e6, 1e-6);
}

TEST(CKernels, PackedPositiveDefiniteAgreesWithEigen) {
  std::mt19937 gen(7);
  std::uniform_real_distribution<double> U(-1, 1);
  int positive = 0, indefinite = 0;
  for (int trial = 0; trial < 200; ++trial) {
    const int d = 1 + trial % 4;
    Mat S(d, d);
    for (int r = 0; r < d; ++r)
      for (int c = r; c < d; ++c) S(r, c) = S(c, r) = U(gen) + (r == c ? 0.6 : 0.0);
    std::vector<double> packed{42.0};  // an offset of 1 into the observer state
    for (int r = 0; r < d; ++r)
      for (int c = r; c < d; ++c) packed.push_back(S(r, c));
    std::vector<double> work(static_cast<std::size_t>(d * d + d));
    const bool pd = kd::obsynth_packed_positive_definite(packed.data(), 1, d, work.data()) != 0;
    EXPECT_EQ(pd, S.llt().info() == Eigen::Success) << S;
    (pd ? positive : indefinite)++;
    std::vector<double> unpacked(static_cast<std::size_t>(d * d));
    kd::obsynth_unpack_symmetric(packed.data(), 1, d, unpacked.data());
    EXPECT_EQ(matrix(unpacked, d), S);
  }
  EXPECT_GT(positive, 20);  // both kinds were exercised
  EXPECT_GT(indefinite, 20);
}

// The exact step: against Phi w + Gamma c from Eigen's matrix exponential (an independent
// oracle), and the C++ runtime's ExactLinearStep::apply (Eigen packets, the kernel's order of
// operations) bit for bit. For the bitwise part A = u v^T / 8 with v^T u = 0 (A^2 = 0, every
// entry a dyadic rational, dt = 1/4): E = A dt and Gamma = dt I + A dt^2 / 2 are then computed
// exactly in either storage order, so any difference is the step's own arithmetic.
template <class Scalar>
void expect_exact_step_matches_the_runtime(int columns) {
  constexpr int n = 4;
  const double u[n] = {1, 2, 1, 2}, v[n] = {2, -1, 2, -1};
  Eigen::Matrix<Scalar, n, n> A;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) A(i, j) = Scalar(u[i] * v[j] / 8);
  const Scalar dt = Scalar(0.25);
  const bool increment = obsynth::ExactLinearStep<Scalar, n>::kIncrement;
  Scalar E[n * n], G[n * n], work[4 * n * n], rowsA[n * n];
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) rowsA[i * n + j] = A(i, j);
  ASSERT_TRUE(obsynth::c::discretise(rowsA, n, dt, E, G, work));
  if (!increment)
    for (int i = 0; i < n; ++i) E[i * n + i] += Scalar(1);
  std::mt19937 gen(columns);
  std::uniform_real_distribution<double> U(-10, 10);
  for (int trial = 0; trial < 50; ++trial) {
    Eigen::Matrix<Scalar, n, 1> w, next;
    for (int i = 0; i < n; ++i) w(i) = Scalar(U(gen));
    Scalar kernel[n];
    if (columns == n) {
      Eigen::Matrix<Scalar, n, 1> c;
      for (int i = 0; i < n; ++i) c(i) = Scalar(U(gen));
      obsynth::ExactLinearStep<Scalar, n> step;
      ASSERT_TRUE(step.prepare(A, dt));
      next = step.apply(w, c);
      obsynth::c::exact_step(E, G, w.data(), c.data(), n, n, increment, kernel);
    } else {  // one held input through B = (1, -1/2, 2, 1/4): Gamma B exact as well
      const Eigen::Matrix<Scalar, n, 1> B(Scalar(1), Scalar(-0.5), Scalar(2), Scalar(0.25));
      Scalar GB[n];
      for (int i = 0; i < n; ++i) {
        GB[i] = Scalar(0);
        for (int r = 0; r < n; ++r) GB[i] += G[i * n + r] * B(r);
      }
      Eigen::Matrix<Scalar, 1, 1> b(Scalar(U(gen)));
      obsynth::ExactLinearStep<Scalar, n, 1> step;
      ASSERT_TRUE(step.prepare(A, B, dt));
      next = step.apply(w, b);
      obsynth::c::exact_step(E, GB, w.data(), b.data(), n, 1, increment, kernel);
    }
    for (int i = 0; i < n; ++i) EXPECT_EQ(next(i), kernel[i]) << "row " << i;
  }
}

TEST(CKernels, ExactStepIsTheRuntimesStepBitForBit) {
  expect_exact_step_matches_the_runtime<double>(4);
  expect_exact_step_matches_the_runtime<float>(4);
  expect_exact_step_matches_the_runtime<double>(1);
  expect_exact_step_matches_the_runtime<float>(1);
}

TEST(CKernels, ExactStepMatchesTheMatrixExponential) {
  for (int n : {1, 3, 6}) {
    const Mat A = closed_loop(n, 2.0);
    const double dt = 0.05;
    const Mat X = augmented_exponential(A, dt);
    std::vector<double> E(static_cast<std::size_t>(n * n)), G(E.size()), work(4 * E.size());
    ASSERT_TRUE(kd::obsynth_discretise(rows(A).data(), n, dt, E.data(), G.data(), work.data()));
    Eigen::VectorXd w = Eigen::VectorXd::LinSpaced(n, -1, 2), c = Eigen::VectorXd::Constant(n, 0.5);
    const Eigen::VectorXd expected = X.topLeftCorner(n, n) * w + X.topRightCorner(n, n) * c;
    std::vector<double> next(static_cast<std::size_t>(n));
    kd::obsynth_exact_step(E.data(), G.data(), w.data(), c.data(), n, n, 1, next.data());
    for (int i = 0; i < n; ++i)
      EXPECT_NEAR(next[static_cast<std::size_t>(i)], expected(i), 1e-12 * (1 + expected.norm()));
  }
}

}  // namespace

namespace {

// One RK4 step on w' = A w is the Taylor polynomial of e^{A h} to degree 4 (by hand: every
// stage is a polynomial in A h), here with the last stage written over w0 itself.
TEST(CKernels, Rk4StagesAreTheDegreeFourTaylorStep) {
  constexpr int n = 3;
  const Mat A = closed_loop(n, 1.5);
  const double h = 0.1;
  const Eigen::VectorXd w0 = Eigen::VectorXd::LinSpaced(n, 1, -2);
  const Mat X = A * h;
  const Mat P = Mat::Identity(n, n) + X + X * X / 2 + X * X * X / 6 + X * X * X * X / 24;
  const Eigen::VectorXd expected = P * w0;
  Eigen::VectorXd w = w0, k(n), acc(n), t(n);
  k = A * w;
  kd::obsynth_rk4_stage(0, h, n, w.data(), k.data(), acc.data(), t.data());
  for (int stage = 1; stage <= 3; ++stage) {
    k = A * t;
    kd::obsynth_rk4_stage(stage, h, n, w.data(), k.data(), acc.data(),
                          stage < 3 ? t.data() : w.data());
  }
  for (int i = 0; i < n; ++i) EXPECT_NEAR(w(i), expected(i), 1e-15 * (1 + expected.norm()));
}

TEST(CKernels, SubstepsAreTheCeilingOfTheRatioWithinLimits) {
  EXPECT_EQ(kd::obsynth_substeps(0.01, 0.0), 1);     // no limit
  EXPECT_EQ(kd::obsynth_substeps(0.01, 0.02), 1);    // already short enough
  EXPECT_EQ(kd::obsynth_substeps(0.01, 0.01), 1);    // exactly the limit
  EXPECT_EQ(kd::obsynth_substeps(0.01, 0.004), 3);   // 2.5 -> 3
  EXPECT_EQ(kd::obsynth_substeps(0.01, 0.0025), 4);  // 4 exactly
  EXPECT_EQ(kd::obsynth_substeps(1.0, 1e-9), 4096);  // capped
  EXPECT_EQ(kd::obsynth_substeps(NAN, 0.01), 1);     // not a number: one step (its guards act)
  EXPECT_EQ(kf::obsynth_substeps(0.01f, 0.004f), 3);
}

}  // namespace

namespace {

// The delay line keeps D + 1 slots; the estimate needs D samples. A ramp u = 0.5 t sampled at
// dt = 0.1 has window mean (the last D samples) and least-squares slope 0.5 by hand.
TEST(CKernels, DelayLineLevelAndSlopeByHand) {
  constexpr int D = 4, filters = 1;
  std::vector<double> ring((D + 1) * filters, 0.0), u_ring(D + 1, 0.0);
  int head = 0, filled = 0;
  const double decay[1] = {0.5}, gain[1] = {2.0};
  int ready = 0;
  for (int k = 1; k <= D; ++k) {
    const double y[1] = {1.0};
    ready = kd::obsynth_delay_push(ring.data(), u_ring.data(), &head, &filled, D, filters, decay,
                                   gain, y, 1, 0.05 * k);
    EXPECT_EQ(ready, k == D ? 1 : 0) << k;
  }
  // z: 0 -> 2 -> 3 -> 3.5 -> 3.75 (z <- z/2 + 2)
  EXPECT_DOUBLE_EQ(ring[static_cast<std::size_t>(head)], 3.75);
  int level = -1;
  double frac = -1, slope = -1;
  // window mean of 0.05, 0.10, 0.15, 0.20 = 0.125; levels at lo = 0, step = 0.1: 1.25
  kd::obsynth_delay_level(u_ring.data(), head, D, 0.2, 1, &slope, 0.1, 0.0, 0.1, 5, 0, 1, &level,
                          &frac);
  EXPECT_EQ(level, 1);
  EXPECT_NEAR(frac, 0.25, 1e-12);
  EXPECT_NEAR(slope, 0.5, 1e-12);
  kd::obsynth_delay_level(u_ring.data(), head, D, 0.2, 0, nullptr, 0.1, 0.0, 0.1, 5, 1, 0, &level,
                          nullptr);
  EXPECT_EQ(level, 2);  // nearest level of 0.2 / 0.1
  kd::obsynth_delay_level(u_ring.data(), head, D, 9.0, 0, nullptr, 0.1, 0.0, 0.1, 5, 1, 0, &level,
                          nullptr);
  EXPECT_EQ(level, 4);  // clamped
}

// Two grid points x = 0 and x = 1 with table values q = 0 and q = 1, eta = 0.25 (ring newest
// 0.25, oldest 0, no delay term, M = 1): weights (eps + |eta - q|)^-2 with eps = 0.5 are
// 1/0.75^2 and 1/1.25^2, so x = (1/1.5625) / (1/0.5625 + 1/1.5625) = 0.5625 / 2.125.
TEST(CKernels, DelayEstimateIsTheKernelWeightedMeanByHand) {
  const double lo[1] = {0.0}, step[1] = {1.0}, q[2] = {0.0, 1.0}, delay[1] = {0.0},
               metric[1] = {1.0};
  const int count[1] = {2};
  const kd::obsynth_delay_grid grid{1, 2, lo, step, count};
  const double ring[2] = {0.25, 0.0};  // head 0 is the newest, slot 1 the oldest (D = 1)
  double work[2], x[1];
  int idx[1];
  kd::obsynth_delay_estimate(&grid, ring, 0, 1, 1, delay, metric, q, nullptr, 0.0, nullptr, nullptr,
                             0.0, 0.5, 2, work, idx, x);
  EXPECT_NEAR(x[0], 0.5625 / 2.125, 1e-15);
}

}  // namespace
