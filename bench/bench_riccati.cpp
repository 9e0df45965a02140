// ns per step() of the James-Baras Riccati observer (seed 000 eq. 2.1-2.2), Google Benchmark.
//
//   seed003/generated/<S>   slawinski17_riccati.hpp (emitted at build time, --Q0 1 --N 1 --R 1)
//   seed003/expert/<S>      hand-written joint (m, Q) RK4 step: scalar code with the Jacobian
//                           A = [[u, -1], [-m2, -m1]] and H = [1, 0] written out, Q symmetric
//                           (3 entries), the 2x2 positive-definiteness test Q11 > 0, det Q > 0
//   seed003/textbook/<S>    textbook Eigen: m and Q as Vector2 / Matrix2, every stage builds A,
//                           H, K = Q H^T R^-1 and dQ = A Q + Q A^T - Q H^T R^-1 H Q + N N^T
//                           with dense products; RK4 over (m, Q); LLT check after the step
//   chain<n>/{generated,expert}/{double,float}, chain<n>/textbook/double   n = 2, 3, 4, 6, 8:
//                           the observer of x_i' = -x_i + sin(x_{i+1}) (i < n),
//                           x_n' = -(1 + x1/4) x_n + u, y = x1 (generated at build time; the
//                           expert (scalar, structure written in) and textbook ones are
//                           generic in n): how the cost grows with n
//                           (n + n(n+1)/2 observer states)
// All of one kind see the same samples (plant simulated in double, fixed dt = 0.01, u held).
// Before timing, the three seed 003 observers run side by side and must agree (1e-12 double),
// and so must each generated chain observer and the expert one.
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "obsynth/eigen.hpp"
#include "obsynth/numeric.hpp"
#include "obsynth/status.hpp"
#include "riccati_chains.hpp"  // generated at build time: the chain headers and their list
#include "slawinski17_riccati.hpp"

namespace {

constexpr std::size_t kSamples = 4096;
constexpr double kDt = 0.01;

// ---- hand-written seed 003 observers ---------------------------------------------------------

template <class Scalar_>
class Expert003 {
 public:
  using Scalar = Scalar_;
  using State = Eigen::Matrix<Scalar, 2, 1>;
  using Input = Eigen::Matrix<Scalar, 1, 1>;
  using Output = Eigen::Matrix<Scalar, 1, 1>;
  void reset(const State& x) noexcept {
    m1_ = x(0), m2_ = x(1), q11_ = 1, q12_ = 0, q22_ = 1;
    xh_ = x;
  }
  obsynth::Status step(Scalar dt, const Input& uin, const Output& yin) noexcept {
    const Scalar u = uin(0), y = yin(0);
    Scalar d[4][5];
    Scalar s[5] = {m1_, m2_, q11_, q12_, q22_};
    const Scalar c[3] = {dt / 2, dt / 2, dt};
    for (int k = 0; k < 4; ++k) {
      const Scalar m1 = s[0], m2 = s[1], a = s[2], b = s[3], cq = s[4];
      const Scalar e = y - m1;
      d[k][0] = -m2 + (Scalar(1) + m1) * u + a * e;
      d[k][1] = -m1 * m2 + u + b * e;
      d[k][2] = Scalar(2) * (u * a - b) - a * a + Scalar(1);
      d[k][3] = u * b - cq - m2 * a - m1 * b - a * b;
      d[k][4] = Scalar(-2) * (m2 * b + m1 * cq) - b * b + Scalar(1);
      if (k < 3) {
        s[0] = m1_ + c[k] * d[k][0];
        s[1] = m2_ + c[k] * d[k][1];
        s[2] = q11_ + c[k] * d[k][2];
        s[3] = q12_ + c[k] * d[k][3];
        s[4] = q22_ + c[k] * d[k][4];
      }
    }
    const Scalar h6 = dt / Scalar(6);
    Scalar w[5];
    const Scalar* prev[5] = {&m1_, &m2_, &q11_, &q12_, &q22_};
    for (int i = 0; i < 5; ++i)
      w[i] = *prev[i] + h6 * (d[0][i] + Scalar(2) * (d[1][i] + d[2][i]) + d[3][i]);
    for (int i = 0; i < 5; ++i)
      if (!obsynth::is_finite(w[i])) return status_ = obsynth::Status::non_finite;
    if (!(w[2] > Scalar(0)) || !(w[2] * w[4] - w[3] * w[3] > Scalar(0)))
      return status_ = obsynth::Status::singular;
    m1_ = w[0], m2_ = w[1], q11_ = w[2], q12_ = w[3], q22_ = w[4];
    xh_(0) = m1_, xh_(1) = m2_;
    return status_ = obsynth::Status::ok;
  }
  const State& estimate() const noexcept { return xh_; }

 private:
  Scalar m1_ = 0, m2_ = 0, q11_ = 1, q12_ = 0, q22_ = 1;
  State xh_ = State::Zero();
  obsynth::Status status_ = obsynth::Status::ok;
};

template <class Scalar_>
class Textbook003 {
 public:
  using Scalar = Scalar_;
  using State = Eigen::Matrix<Scalar, 2, 1>;
  using Input = Eigen::Matrix<Scalar, 1, 1>;
  using Output = Eigen::Matrix<Scalar, 1, 1>;
  using Mat = Eigen::Matrix<Scalar, 2, 2>;
  void reset(const State& x) noexcept {
    m_ = x;
    Q_.setIdentity();
  }
  obsynth::Status step(Scalar dt, const Input& uin, const Output& yin) noexcept {
    const Scalar u = uin(0), y = yin(0);
    const Mat NNt = Mat::Identity();
    const Scalar Rinv = 1;
    auto rhs = [&](const State& m, const Mat& Q, State& dm, Mat& dQ) {
      Mat A;
      A << u, -1, -m(1), -m(0);
      Eigen::Matrix<Scalar, 1, 2> H;
      H << 1, 0;
      const State f(-m(1) + (Scalar(1) + m(0)) * u, -m(0) * m(1) + u);
      const State K = Q * H.transpose() * Rinv;
      dm = f + K * (y - m(0));
      dQ = A * Q + Q * A.transpose() - Q * H.transpose() * Rinv * H * Q + NNt;
    };
    State k1m, k2m, k3m, k4m;
    Mat k1Q, k2Q, k3Q, k4Q;
    rhs(m_, Q_, k1m, k1Q);
    rhs(m_ + dt / 2 * k1m, Q_ + dt / 2 * k1Q, k2m, k2Q);
    rhs(m_ + dt / 2 * k2m, Q_ + dt / 2 * k2Q, k3m, k3Q);
    rhs(m_ + dt * k3m, Q_ + dt * k3Q, k4m, k4Q);
    const Scalar two(2);
    const State m = m_ + dt / 6 * (k1m + two * k2m + two * k3m + k4m);
    const Mat Q = Q_ + dt / 6 * (k1Q + two * k2Q + two * k3Q + k4Q);
    if (!m.allFinite() || !Q.allFinite()) return obsynth::Status::non_finite;
    if (Eigen::LLT<Mat>(Q).info() != Eigen::Success) return obsynth::Status::singular;
    m_ = m;
    Q_ = Q;
    return obsynth::Status::ok;
  }
  const State& estimate() const noexcept { return m_; }

 private:
  State m_ = State::Zero();
  Mat Q_ = Mat::Identity();
};

// Textbook Eigen observer of the chain family (any n): A and H written out by hand.
template <int N>
class TextbookChain {
 public:
  using Scalar = double;
  using State = Eigen::Matrix<double, N, 1>;
  using Input = Eigen::Matrix<double, 1, 1>;
  using Output = Eigen::Matrix<double, 1, 1>;
  using Mat = Eigen::Matrix<double, N, N>;
  void reset(const State& x) noexcept {
    m_ = x;
    Q_.setIdentity();
  }
  obsynth::Status step(double dt, const Input& uin, const Output& yin) noexcept {
    const double u = uin(0), y = yin(0);
    auto rhs = [&](const State& m, const Mat& Q, State& dm, Mat& dQ) {
      Mat A = Mat::Zero();
      State f;
      for (int i = 0; i + 1 < N; ++i) {
        f(i) = -m(i) + std::sin(m(i + 1));
        A(i, i) = -1;
        A(i, i + 1) = std::cos(m(i + 1));
      }
      f(N - 1) = -(1 + m(0) / 4) * m(N - 1) + u;
      A(N - 1, N - 1) = -(1 + m(0) / 4);
      A(N - 1, 0) += -m(N - 1) / 4;
      Eigen::Matrix<double, 1, N> H = Eigen::Matrix<double, 1, N>::Zero();
      H(0) = 1;
      dm = f + Q * H.transpose() * (y - m(0));
      dQ = A * Q + Q * A.transpose() - Q * H.transpose() * H * Q + Mat::Identity();
    };
    State k1m, k2m, k3m, k4m;
    Mat k1Q, k2Q, k3Q, k4Q;
    rhs(m_, Q_, k1m, k1Q);
    rhs(m_ + dt / 2 * k1m, Q_ + dt / 2 * k1Q, k2m, k2Q);
    rhs(m_ + dt / 2 * k2m, Q_ + dt / 2 * k2Q, k3m, k3Q);
    rhs(m_ + dt * k3m, Q_ + dt * k3Q, k4m, k4Q);
    const State m = m_ + dt / 6 * (k1m + 2 * k2m + 2 * k3m + k4m);
    const Mat Q = Q_ + dt / 6 * (k1Q + 2 * k2Q + 2 * k3Q + k4Q);
    if (!m.allFinite() || !Q.allFinite()) return obsynth::Status::non_finite;
    if (Eigen::LLT<Mat>(Q).info() != Eigen::Success) return obsynth::Status::singular;
    m_ = m;
    Q_ = Q;
    return obsynth::Status::ok;
  }
  const State& estimate() const noexcept { return m_; }

 private:
  State m_ = State::Zero();
  Mat Q_ = Mat::Identity();
};

// Hand-written expert observer of the chain family (any n, float or double): scalar code on
// the packed state w = (m, Q upper triangle row by row), the structure written in by hand:
// A = D_x F has A(i, i) = -1, A(i, i+1) = cos(m_{i+1}) (i < n), A(n, n) = -(1 + m1/4),
// A(n, 1) = -m_n/4, and H = e1, so Q H^T H Q = q_1 q_1^T (q_1 the first column of Q) and
// (A Q)_ij takes two entries of Q. Only the upper triangle of Q' is formed. RK4 on plain arrays;
// the step is rejected when w is not finite or Q has no Cholesky factor (pivots > 0).
template <int N, class Scalar_>
class ExpertChain {
 public:
  using Scalar = Scalar_;
  using State = Eigen::Matrix<Scalar, N, 1>;
  using Input = Eigen::Matrix<Scalar, 1, 1>;
  using Output = Eigen::Matrix<Scalar, 1, 1>;
  static constexpr int NW = N + N * (N + 1) / 2;
  void reset(const State& x) noexcept {
    for (int i = 0; i < NW; ++i) w_[i] = 0;
    for (int i = 0; i < N; ++i) w_[i] = x(i), w_[at(i, i)] = 1;
    xh_ = x;
  }
  obsynth::Status step(Scalar dt, const Input& uin, const Output& yin) noexcept {
    const Scalar u = uin(0), y = yin(0);
    Scalar k[NW], acc[NW], s[NW];
    const Scalar h2 = dt / 2;
    rhs(w_, u, y, k);
#pragma GCC unroll 64
    for (int i = 0; i < NW; ++i) acc[i] = k[i], s[i] = w_[i] + h2 * k[i];
    rhs(s, u, y, k);
#pragma GCC unroll 64
    for (int i = 0; i < NW; ++i) acc[i] += Scalar(2) * k[i], s[i] = w_[i] + h2 * k[i];
    rhs(s, u, y, k);
#pragma GCC unroll 64
    for (int i = 0; i < NW; ++i) acc[i] += Scalar(2) * k[i], s[i] = w_[i] + dt * k[i];
    rhs(s, u, y, k);
    const Scalar h6 = dt / Scalar(6);
#pragma GCC unroll 64
    for (int i = 0; i < NW; ++i) s[i] = w_[i] + h6 * (acc[i] + k[i]);
    for (int i = 0; i < NW; ++i)
      if (!obsynth::is_finite(s[i])) return obsynth::Status::non_finite;
    // Cholesky pivots of Q (upper triangle, row by row): Q = U^T U.
    Scalar U[N][N];
    for (int i = 0; i < N; ++i) {
      for (int j = i; j < N; ++j) {
        Scalar v = s[at(i, j)];
        for (int k2 = 0; k2 < i; ++k2) v -= U[k2][i] * U[k2][j];
        if (j == i) {
          if (!(v > Scalar(0))) return obsynth::Status::singular;
          U[i][i] = std::sqrt(v);
        } else {
          U[i][j] = v / U[i][i];
        }
      }
    }
    for (int i = 0; i < NW; ++i) w_[i] = s[i];
    for (int i = 0; i < N; ++i) xh_(i) = w_[i];
    return obsynth::Status::ok;
  }
  const State& estimate() const noexcept {
    return xh_;
  }

 private:
  static constexpr int at(int r, int c) noexcept {
    return N + r * N - r * (r - 1) / 2 + (c - r);
  }
  static Scalar q(const Scalar* w, int i, int j) noexcept {
    return i <= j ? w[at(i, j)] : w[at(j, i)];
  }
  static void rhs(const Scalar* w, Scalar u, Scalar y, Scalar* d) noexcept {
    Scalar c[N];
    const Scalar e = y - w[0];
    const Scalar a = -(Scalar(1) + w[0] / Scalar(4)), b = -w[N - 1] / Scalar(4);
#pragma GCC unroll 16
    for (int i = 0; i + 1 < N; ++i) {
      c[i] = std::cos(w[i + 1]);
      d[i] = -w[i] + std::sin(w[i + 1]) + q(w, 0, i) * e;
    }
    d[N - 1] = a * w[N - 1] + u + q(w, 0, N - 1) * e;
    auto AQ = [&](int i, int j) noexcept {
      return i + 1 < N ? -q(w, i, j) + c[i] * q(w, i + 1, j) : a * q(w, i, j) + b * q(w, 0, j);
    };
#pragma GCC unroll 16
    for (int i = 0; i < N; ++i) {
#pragma GCC unroll 16
      for (int j = i; j < N; ++j)
        d[at(i, j)] = AQ(i, j) + AQ(j, i) - q(w, i, 0) * q(w, j, 0) + Scalar(i == j ? 1 : 0);
    }
  }
  Scalar w_[NW] = {};
  State xh_ = State::Zero();
};

// ---- samples ---------------------------------------------------------------------------------

struct Samples {
  int n = 0;
  std::vector<double> u, y, x0;
};

// The plant x' = F(x, u) (F given), u = 0.5 sin(1.1 t) + 0.2 sin(3.7 t), y = x1, 8 RK4
// sub-steps per sample, from x0.
template <int N, class Field>
Samples make_samples(const Eigen::Matrix<double, N, 1>& x0, Field&& F) {
  Samples s;
  s.n = N;
  s.x0.assign(x0.data(), x0.data() + N);
  Eigen::Matrix<double, N, 1> x = x0, k1, k2, k3, k4;
  double t = 0;
  const double h = kDt / 8;
  for (std::size_t k = 0; k < kSamples; ++k) {
    const double u = 0.5 * std::sin(1.1 * t) + 0.2 * std::sin(3.7 * t);
    s.u.push_back(u);
    s.y.push_back(x(0));
    for (int j = 0; j < 8; ++j) {
      F(x, u, k1);
      F(x + h / 2 * k1, u, k2);
      F(x + h / 2 * k2, u, k3);
      F(x + h * k3, u, k4);
      x += h / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
    }
    t += kDt;
  }
  return s;
}

const Samples& seed003_samples() {
  static const Samples s =
      make_samples<2>(Eigen::Vector2d(0.5, -0.5), [](const auto& x, double u, auto& dx) {
        dx(0) = -x(1) + (1 + x(0)) * u;
        dx(1) = -x(0) * x(1) + u;
      });
  return s;
}

template <int N>
const Samples& chain_samples() {
  static const Samples s = make_samples<N>(Eigen::Matrix<double, N, 1>::Constant(0.3),
                                           [](const auto& x, double u, auto& dx) {
                                             for (int i = 0; i + 1 < N; ++i)
                                               dx(i) = -x(i) + std::sin(x(i + 1));
                                             dx(N - 1) = -(1 + x(0) / 4) * x(N - 1) + u;
                                           });
  return s;
}

template <class Obs>
struct Arrays {
  using S = typename Obs::Scalar;
  std::vector<typename Obs::Input> u;
  std::vector<typename Obs::Output> y;
  typename Obs::State xh0;
  explicit Arrays(const Samples& s) {
    for (std::size_t k = 0; k < kSamples; ++k) {
      typename Obs::Input uu;
      uu(0) = static_cast<S>(s.u[k]);
      typename Obs::Output yy;
      yy(0) = static_cast<S>(s.y[k]);
      u.push_back(uu);
      y.push_back(yy);
    }
    for (int i = 0; i < s.n; ++i) xh0(i) = static_cast<S>(s.x0[static_cast<std::size_t>(i)] + 0.4);
  }
};

template <class Obs>
void step_benchmark(benchmark::State& st, const Samples& s) {
  static const Arrays<Obs> a(s);
  Obs obs;
  obs.reset(a.xh0);
  const auto dt = static_cast<typename Obs::Scalar>(kDt);
  const auto* u = a.u.data();
  const auto* y = a.y.data();
  std::size_t i = 0;
  long failures = 0;
  for (auto _ : st) {
    failures += obs.step(dt, u[i], y[i]) != obsynth::Status::ok;
    benchmark::DoNotOptimize(obs.estimate());
    i = (i + 1) & (kSamples - 1);
  }
  st.counters["failures"] = static_cast<double>(failures);
}

template <class S>
using Generated003 = obsynth_gen::slawinski17::Slawinski17Riccati<S>;

// The three seed 003 observers agree step by step (double).
bool seed003_agree() {
  const Samples& s = seed003_samples();
  const Arrays<Generated003<double>> a(s);
  Generated003<double> g;
  Expert003<double> e;
  Textbook003<double> t;
  g.reset(a.xh0), e.reset(a.xh0), t.reset(a.xh0);
  double diff = 0;
  int failures = 0;
  for (std::size_t k = 0; k < kSamples; ++k) {
    failures += g.step(kDt, a.u[k], a.y[k]) != obsynth::Status::ok;
    failures += e.step(kDt, a.u[k], a.y[k]) != obsynth::Status::ok;
    failures += t.step(kDt, a.u[k], a.y[k]) != obsynth::Status::ok;
    diff = std::fmax(diff, (g.estimate() - e.estimate()).cwiseAbs().maxCoeff());
    diff = std::fmax(diff, (g.estimate() - t.estimate()).cwiseAbs().maxCoeff());
  }
  std::printf("seed 003 agreement: max |xh_generated - xh_hand| = %.3g, failures %d\n", diff,
              failures);
  return diff <= 1e-12 && failures == 0;
}

// The generated chain observer and the agreement check against the expert one (double).
template <int N, template <class> class Gen>
bool chain_agree(const char* name) {
  const Samples& s = chain_samples<N>();
  const Arrays<Gen<double>> a(s);
  Gen<double> g;
  ExpertChain<N, double> e;
  g.reset(a.xh0), e.reset(a.xh0);
  double diff = 0;
  int failures = 0;
  for (std::size_t k = 0; k < kSamples; ++k) {
    failures += g.step(kDt, a.u[k], a.y[k]) != obsynth::Status::ok;
    failures += e.step(kDt, a.u[k], a.y[k]) != obsynth::Status::ok;
    diff = std::fmax(diff, (g.estimate() - e.estimate()).cwiseAbs().maxCoeff());
  }
  std::printf("%s agreement: max |xh_generated - xh_expert| = %.3g, failures %d\n", name, diff,
              failures);
  return diff <= 1e-12 && failures == 0;
}

template <int N, template <class> class Gen>
void register_chain(const char* name) {
  const std::string p(name);
  benchmark::RegisterBenchmark((p + "/generated/double").c_str(), [](benchmark::State& st) {
    step_benchmark<Gen<double>>(st, chain_samples<N>());
  });
  benchmark::RegisterBenchmark((p + "/expert/double").c_str(), [](benchmark::State& st) {
    step_benchmark<ExpertChain<N, double>>(st, chain_samples<N>());
  });
  benchmark::RegisterBenchmark((p + "/textbook/double").c_str(), [](benchmark::State& st) {
    step_benchmark<TextbookChain<N>>(st, chain_samples<N>());
  });
  benchmark::RegisterBenchmark((p + "/generated/float").c_str(), [](benchmark::State& st) {
    step_benchmark<Gen<float>>(st, chain_samples<N>());
  });
  benchmark::RegisterBenchmark((p + "/expert/float").c_str(), [](benchmark::State& st) {
    step_benchmark<ExpertChain<N, float>>(st, chain_samples<N>());
  });
}

}  // namespace

int main(int argc, char** argv) {
  if (!seed003_agree()) return 1;
  benchmark::RegisterBenchmark("seed003/generated/double", [](benchmark::State& st) {
    step_benchmark<Generated003<double>>(st, seed003_samples());
  });
  benchmark::RegisterBenchmark("seed003/expert/double", [](benchmark::State& st) {
    step_benchmark<Expert003<double>>(st, seed003_samples());
  });
  benchmark::RegisterBenchmark("seed003/textbook/double", [](benchmark::State& st) {
    step_benchmark<Textbook003<double>>(st, seed003_samples());
  });
  benchmark::RegisterBenchmark("seed003/generated/float", [](benchmark::State& st) {
    step_benchmark<Generated003<float>>(st, seed003_samples());
  });
  benchmark::RegisterBenchmark("seed003/expert/float", [](benchmark::State& st) {
    step_benchmark<Expert003<float>>(st, seed003_samples());
  });
  benchmark::RegisterBenchmark("seed003/textbook/float", [](benchmark::State& st) {
    step_benchmark<Textbook003<float>>(st, seed003_samples());
  });
  bool agree = true;
#define OBSYNTH_CHAIN_AGREE(N, NS, CLASS) \
  agree = chain_agree<N, obsynth_gen::NS::CLASS>("chain" #N) && agree;
  OBSYNTH_RICCATI_CHAINS(OBSYNTH_CHAIN_AGREE)
  if (!agree) return 1;
#define OBSYNTH_REGISTER_CHAIN(N, NS, CLASS) register_chain<N, obsynth_gen::NS::CLASS>("chain" #N);
  OBSYNTH_RICCATI_CHAINS(OBSYNTH_REGISTER_CHAIN)
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
