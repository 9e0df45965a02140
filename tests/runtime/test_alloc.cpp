// SPDX-License-Identifier: MIT
// Copyright (c) obsynth authors
//
// Zero-allocation checks for the runtime and the reference observer, using the global
// allocation hooks of alloc_counter.cpp (this executable only).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <vector>

#include "../../bench/handwritten_seed003.hpp"
#include "alloc_counter.hpp"
#include "obsynth/differentiator.hpp"
#include "obsynth/integrators.hpp"
#include "obsynth/newton.hpp"

namespace {

using obsynth::test::AllocationCounter;

// Volatile sinks keep the compiler from eliding allocation/free pairs.
void* volatile g_sink = nullptr;

TEST(AllocCounter, CountsOperatorNew) {
  // The compiler may elide a new-expression whose result does not escape ([expr.new]/10), so
  // every pointer is published through a volatile sink first.
  AllocationCounter c;
  int* p = new int(42);
  g_sink = p;
  delete p;
  double* a = new double[10];
  g_sink = a;
  delete[] a;
  void* raw = ::operator new(64);  // direct calls are never elided
  g_sink = raw;
  ::operator delete(raw);
  const std::size_t allocs = c.allocations();
  const std::size_t frees = c.deallocations();
  const std::size_t bytes = c.bytes();
  EXPECT_EQ(allocs, 3u);
  EXPECT_EQ(frees, 3u);
  EXPECT_EQ(bytes, sizeof(int) + 10 * sizeof(double) + 64);
}

TEST(AllocCounter, CountsStandardContainers) {
  AllocationCounter c;
  {
    std::vector<double> v(100, 1.0);
    g_sink = v.data();
  }
  const std::size_t allocs = c.allocations();
  EXPECT_GE(allocs, 1u);
  EXPECT_EQ(c.deallocations(), allocs);
}

TEST(AllocCounter, CountsAlignedNew) {
  struct alignas(64) Big {
    double d[8];
  };
  AllocationCounter c;
  Big* b = new Big();
  g_sink = b;
  delete b;
  EXPECT_EQ(c.allocations(), 1u);
  EXPECT_EQ(c.deallocations(), 1u);
}

TEST(AllocCounter, CountsMallocFamilyWhenHooked) {
  if (!obsynth::test::malloc_hooks_active()) {
    GTEST_SKIP() << "malloc hooks inactive (non-glibc or sanitizer build)";
  }
  AllocationCounter c;
  void* p = std::malloc(16);
  g_sink = p;
  p = std::realloc(p, 64);
  g_sink = p;
  std::free(p);
  void* q = std::calloc(4, 8);
  g_sink = q;
  std::free(q);
  void* r = nullptr;
  ASSERT_EQ(posix_memalign(&r, 64, 128), 0);
  g_sink = r;
  std::free(r);
  void* s = std::aligned_alloc(32, 64);
  g_sink = s;
  std::free(s);
  const std::size_t allocs = c.allocations();
  EXPECT_EQ(allocs, 5u);  // malloc, realloc, calloc, posix_memalign, aligned_alloc
  EXPECT_EQ(c.deallocations(), 5u);  // realloc released the old block, then 4 frees
}

TEST(AllocCounter, EigenDynamicMatrixIsSeen) {
  if (!obsynth::test::malloc_hooks_active()) {
    GTEST_SKIP() << "Eigen allocates with std::malloc, not hooked in this build";
  }
  AllocationCounter c;
  {
    Eigen::MatrixXd m(10, 10);
    m.setRandom();
    g_sink = m.data();
  }
  EXPECT_EQ(c.allocations(), 1u);
}

template <class Scalar>
std::size_t allocations_in_runtime_calls() {
  using V2 = Eigen::Matrix<Scalar, 2, 1>;
  using M2 = Eigen::Matrix<Scalar, 2, 2>;
  using V6 = Eigen::Matrix<Scalar, 6, 1>;
  using M6 = Eigen::Matrix<Scalar, 6, 6>;
  using Obs = handwritten::seed003::CanonicalObserver<Scalar>;

  // Objects are constructed before counting starts; only the per-step work is measured.
  Obs obs;
  obs.reset(V2(Scalar(0.1f), Scalar(0.2f)));
  typename Obs::Input u;
  u << Scalar(0.3f);
  typename Obs::Output y;
  y << Scalar(0.5f);
  obsynth::JetDifferentiator<Scalar, 3> diff(Scalar(0.05f));
  diff.reset(Scalar(0));
  V6 x6 = V6::Constant(Scalar(0.1f));
  M6 B = M6::Identity() * Scalar(0.2f);
  B(0, 5) = Scalar(0.1f);
  B(4, 1) = Scalar(-0.3f);
  auto rhs6 = [&B](const V6& x, V6& dx) noexcept {
    dx = -x + (B * x).array().tanh().matrix();
  };
  auto T6 = [&B](const V6& x, V6& z) noexcept { z = x + Scalar(0.3f) * (B * x).array().tanh().matrix(); };
  auto J6 = [&B](const V6& x, M6& j) noexcept {
    j = M6::Identity();
    const V6 c = (B * x).array().cosh().matrix();
    for (int i = 0; i < 6; ++i) j.row(i) += Scalar(0.3f) / (c(i) * c(i)) * B.row(i);
  };
  auto Tinv6 = [&J6](const V6& x, M6& t) noexcept {
    M6 j;
    J6(x, j);
    t = j.inverse();
  };
  const V6 z6 = V6::LinSpaced(Scalar(-0.5f), Scalar(0.5f));
  auto T2 = [](const V2& x, V2& z) noexcept { z = Obs::T(x); };
  auto tau2 = [](const V2& x, M2& t) noexcept { t << Scalar(0), Scalar(1), Scalar(-1), x(0); };
  const Scalar tol = sizeof(Scalar) == 4 ? Scalar(1e-5f) : Scalar(1e-12);

  AllocationCounter c;
  for (int i = 0; i < 100; ++i) {
    const Scalar t = static_cast<Scalar>(i) * Scalar(1e-3f);
    obs.step(Scalar(1e-3f), u, y);
    diff.update(i % 2 == 0 ? Scalar(1e-3f) : Scalar(2e-3f), std::sin(t));  // Phi recomputed
    obsynth::euler_step<Scalar, 6>(rhs6, Scalar(1e-3f), x6);
    obsynth::heun_step<Scalar, 6>(rhs6, Scalar(1e-3f), x6);
    obsynth::rk4_step<Scalar, 6>(rhs6, Scalar(1e-3f), x6);
    V6 xa = V6::Zero();
    obsynth::newton_solve_jacobian<Scalar, 6>(T6, J6, z6, xa, 10, tol);
    V6 xb = V6::Zero();
    obsynth::newton_solve_inverse_jacobian<Scalar, 6>(T6, Tinv6, z6, xb, 10, tol);
    V2 x2 = V2::Zero();
    obsynth::newton_solve_inverse_jacobian<Scalar, 2>(T2, tau2, obs.z_estimate(), x2, 10, tol);
    g_sink = &x2;
  }
  return c.allocations();
}

TEST(ZeroAllocation, RuntimeAndReferenceObserverDouble) {
  EXPECT_EQ(allocations_in_runtime_calls<double>(), 0u);
}

TEST(ZeroAllocation, RuntimeAndReferenceObserverFloat) {
  EXPECT_EQ(allocations_in_runtime_calls<float>(), 0u);
}

}  // namespace
