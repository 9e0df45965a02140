// Deciding whether an expression is identically zero, three-valued:
//   proved  - symbolic normalisation (after a sound rewrite of sin/cos/tan/tanh/exp into
//             rational functions of base atoms) gives exactly 0;
//   numeric - not proved, but zero at every sampled point (Digits >= 40, random rationals
//             with large prime denominators inside the model's domain box, then points at the
//             expression's own scales, see scaled_points): evidence, never a proof;
//   nonzero - some sampled point gives a value that is clearly not zero.
#pragma once

#include <ginac/ginac.h>

#include <cstdint>
#include <string>
#include <vector>

#include "foundation/expr.hpp"

namespace obsynth {

enum class ZeroVerdict { proved, numeric, nonzero };
const char* verdict_name(ZeroVerdict v);
inline bool is_zero_verdict(ZeroVerdict v) {
  return v != ZeroVerdict::nonzero;
}

struct ZeroTestOptions {
  int points = 8;   // sample points: 2 near opposite box corners, the rest random
  int digits = 40;  // decimal digits for numeric evaluation
  std::uint64_t seed = 0x5eed0b5;
};

// Rewrites sin/cos/tan (Weierstrass substitution on base angles), exp and tanh (powers of
// base exponentials) and replaces remaining transcendental atoms by fresh symbols, so that
// normal() of the result is zero only if the input is identically zero.
GiNaC::ex rational_rewrite(const GiNaC::ex& e);

// Symbolic part only: true if proved identically zero.
bool proved_zero(const GiNaC::ex& e);

ZeroVerdict zero_test(const GiNaC::ex& e, const SampleBoxes& boxes,
                      const ZeroTestOptions& opt = {});

// The verdict with its evidence: how many points it vanished at, or where it did not.
struct ZeroTestResult {
  ZeroVerdict verdict = ZeroVerdict::nonzero;
  int zero_points = 0;           // points where the value was zero within rounding
  GiNaC::exmap witness;          // nonzero: a point where the value is clearly not zero
  GiNaC::numeric witness_value;  // the value there
};
ZeroTestResult zero_test_detailed(const GiNaC::ex& e, const SampleBoxes& boxes,
                                  const ZeroTestOptions& opt = {});

// Points at the scales of e, tried before a numeric verdict: uniform points miss where a steep
// function is not degenerate (tanh(100 w) sech^2(100 w) on w in [-800, 800] is zero within
// rounding outside |w| < 0.5). For each decade 10^-1 .. 10^-12 of the box, one point with every
// symbol that fraction of the box away from the box's point nearest 0; and, for each argument
// of sin, cos, tan, tanh, exp, atan or log that is linear in a symbol, a point where the
// argument is of order one.
std::vector<GiNaC::exmap> scaled_points(const GiNaC::ex& e,
                                        const std::vector<GiNaC::symbol>& symbols,
                                        const SampleBoxes& boxes, std::uint64_t seed);

// Evaluates e at the given exact point with `digits` decimal digits; returns false when the
// value is undefined or not real there.
bool evaluate_real(const GiNaC::ex& e, const GiNaC::exmap& point, int digits,
                   GiNaC::numeric& value);

// Deterministic random points (exact rationals with large prime denominators) in the boxes of
// the given symbols.
// Like evaluate_real, also returning a magnitude bound: the value the expression would have
// with every sum replaced by the sum of its terms' magnitudes. Rounding errors are relative to
// it, so |value| <= 10^-(digits-10) * magnitude means "zero within rounding": a cancellation
// such as sin^2 + cos^2 - 1 evaluates to noise whose size says nothing by itself.
bool evaluate_with_magnitude(const GiNaC::ex& e, const GiNaC::exmap& point, int digits,
                             GiNaC::numeric& value, GiNaC::numeric& magnitude);

std::vector<GiNaC::exmap> sample_points(const std::vector<GiNaC::symbol>& symbols,
                                        const SampleBoxes& boxes, int count, std::uint64_t seed);

// RAII save/restore of GiNaC's global Digits.
class DigitsGuard {
 public:
  explicit DigitsGuard(long digits);
  ~DigitsGuard();
  DigitsGuard(const DigitsGuard&) = delete;
  DigitsGuard& operator=(const DigitsGuard&) = delete;

 private:
  long saved_;
};

}  // namespace obsynth
