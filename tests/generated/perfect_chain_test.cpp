// A generated perfect observer of a constructed chain (n = 2..6): reconstruct() from the
// exact output jets (perfect_reference.cpp: y^(k) = L_F^k h by GiNaC, input held constant, so
// its derivatives are zero) gives back the state, in double and float, under the contract
// flags; the observer class meets the runtime interface and steps without failing.
#include <cmath>
#include <cstdio>

#include OBSYNTH_PERFECT_HEADER
#include OBSYNTH_REFERENCE_HEADER

namespace gen = obsynth_gen::OBSYNTH_NS;

namespace {

int passed = 0, failed = 0;

template <class Scalar>
void reconstruct_from_exact_jets(double tol) {
  using F = gen::PerfectFunctions<Scalar>;
  for (int k = 0; k < ref::kPoints; ++k) {
    typename F::YJet yj;
    typename F::UJet uj = F::UJet::Zero();
    for (int i = 0; i < gen::n; ++i) yj(i) = static_cast<Scalar>(ref::yjet[k][i]);
    for (int j = 0; j < gen::m; ++j) uj(j, 0) = static_cast<Scalar>(ref::u[k][j]);
    typename F::State x;
    F::reconstruct(yj, uj, x);
    double scale = 1;
    for (int i = 0; i < gen::n; ++i) scale = std::fmax(scale, std::fabs(ref::x[k][i]));
    for (int i = 0; i < gen::n; ++i) {
      const double got = static_cast<double>(x(i));
      if (std::fabs(got - ref::x[k][i]) <= tol * scale) {
        ++passed;
      } else {
        ++failed;
        std::printf("FAIL: reconstruct point %d x%d: got %.17g, want %.17g\n", k, i + 1, got,
                    ref::x[k][i]);
      }
    }
  }
}

}  // namespace

static_assert(obsynth::is_observer_v<gen::OBSYNTH_CLASS<double>>, "observer interface (double)");
static_assert(obsynth::is_observer_v<gen::OBSYNTH_CLASS<float>>, "observer interface (float)");

int main() {
  reconstruct_from_exact_jets<double>(1e-9);
  // In float the reconstruction of the larger chains cancels terms of size 1e4..1e5 (the
  // jets grow like the derivatives of the output: y^(5) ~ 1e4 here) down to O(1): the float
  // unit roundoff 6e-8 times 1e5 allows errors near 1e-2.
  reconstruct_from_exact_jets<float>(1e-2);
  gen::OBSYNTH_CLASS<double> obs(1e-2);
  obs.reset(gen::OBSYNTH_CLASS<double>::State::Zero());
  gen::OBSYNTH_CLASS<double>::Input u = gen::OBSYNTH_CLASS<double>::Input::Zero();
  gen::OBSYNTH_CLASS<double>::Output y = gen::OBSYNTH_CLASS<double>::Output::Zero();
  for (int k = 0; k < 100; ++k) {
    if (obs.step(1e-3, u, y) == obsynth::Status::ok) {
      ++passed;
    } else {
      ++failed;
      std::printf("FAIL: step %d\n", k);
      break;
    }
  }
  std::printf("%s perfect: %d passed, %d failed\n", OBSYNTH_NAME, passed, failed);
  return failed == 0 ? 0 : 1;
}
