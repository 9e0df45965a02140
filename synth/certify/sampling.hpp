// Deterministic sample points shared by the certificates, the designs' searches and the
// simulator's trials: one radical inverse, so that every sampled figure is reproducible.
#pragma once

#include <cstddef>

namespace obsynth {

// The radical inverse of i in base b (the i-th point of a Halton sequence), in [0, 1).
inline double radical_inverse(std::size_t i, unsigned base) {
  double f = 1, r = 0;
  while (i > 0) {
    f /= base;
    r += f * static_cast<double>(i % base);
    i /= base;
  }
  return r;
}

}  // namespace obsynth
