// The generated high-gain observer of tests/models/hgkt_cubic.sym (O = diag(1, 3 x2^2)) started
// on its singular set x2 = 0: the step is rejected with Status::singular and the state kept, in
// float and double; started off the set, the same step is ok.
#include <cstdio>

#include OBSYNTH_HGKT_HEADER

template <class Scalar>
int run() {
  using Obs = obsynth_gen::hgkt_cubic::HgktCubicHighGain<Scalar>;
  int failures = 0;
  Obs obs;
  typename Obs::State x0;
  x0 << Scalar(0.5), Scalar(0);
  obs.reset(x0);
  typename Obs::Input u;
  typename Obs::Output y;
  y << Scalar(1);
  const auto st = obs.step(Scalar(1e-3), u, y);
  if (st != obsynth::Status::singular || obs.status() != obsynth::Status::singular) ++failures;
  if (!(obs.estimate() == x0)) ++failures;  // state kept
  x0 << Scalar(0.5), Scalar(0.5);
  obs.reset(x0);
  if (obs.step(Scalar(1e-3), u, y) != obsynth::Status::ok) ++failures;
  return failures;
}

int main() {
  const int failures = run<double>() + run<float>();
  std::printf("hgkt_cubic singular O: %d failures\n", failures);
  return failures == 0 ? 0 : 1;
}
