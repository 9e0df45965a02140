// Emission of observer headers (design.md §6 contract): one header per model and method,
// its own namespace, constexpr dimensions, named indices, fixed-size Eigen, templated
// scalar, noexcept, no heap, numeric failure as a status.
#pragma once

#include <string>

#include "analysis/analysis.hpp"
#include "designs/observers.hpp"
#include "emit/cxx.hpp"

namespace obsynth {

struct EmitOptions {
  Precision precision = Precision::double_precision;
  std::string source_name;  // the model path as it appears in the banner
  int newton_iterations = 8;
};

struct EmittedHeader {
  std::string filename;  // <model>_<method>.hpp
  std::string text;
  std::string class_name;
  std::string summary;  // one paragraph for the report
};

EmittedHeader emit_canonical_header(const Analysis& a, const CanonicalDesign& d,
                                    const EmitOptions& opt);
EmittedHeader emit_perfect_header(const Analysis& a, const PerfectDesign& d,
                                  const EmitOptions& opt);

}  // namespace obsynth
