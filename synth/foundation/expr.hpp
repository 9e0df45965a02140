// Value types for expressions and boxes that every layer uses: expression vectors and
// matrices, symbol lists, intervals and the sampling boxes of symbols.
#pragma once

#include <ginac/ginac.h>

#include <map>
#include <string>
#include <vector>

namespace obsynth {

using ExVec = std::vector<GiNaC::ex>;
using ExMatrix = std::vector<ExVec>;  // row-major
using Symbols = std::vector<GiNaC::symbol>;

struct Interval {
  GiNaC::numeric lo, hi;
};

// Sampling boxes for symbols by name; symbols not listed sample from [-2, 2].
struct SampleBoxes {
  std::map<std::string, Interval> by_name;
  Interval box(const GiNaC::symbol& s) const {
    const auto it = by_name.find(s.get_name());
    if (it != by_name.end()) return it->second;
    return {GiNaC::numeric(-2), GiNaC::numeric(2)};
  }
};

}  // namespace obsynth
