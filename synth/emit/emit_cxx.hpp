// The generic C++ emitter: one header per model and design, read from the design's
// ObserverSpec (design.md §6 contract): its own namespace, constexpr dimensions, named
// indices, fixed-size Eigen, templated scalar, noexcept, no heap, numeric failure as a status,
// the model's free parameters as a run-time Params struct.
#pragma once

#include <string>

#include "analysis/analysis.hpp"
#include "designs/spec.hpp"
#include "emit/cxx.hpp"

namespace obsynth {

struct EmitOptions {
  Precision precision = Precision::double_precision;
  std::string source_name;            // the model path as it appears in the banner
  Language language = Language::cpp;  // --language: cpp (one header) or c (.h and .c)
};

struct EmittedHeader {
  std::string filename;  // <model>_<method>.hpp
  std::string text;
  std::string namespace_name;  // obsynth_gen::<namespace_name>
  std::string class_name;
  std::string usage_example;   // a complete program using the class (compiled by a test)
  std::size_t operations = 0;  // arithmetic operations in the generated functions
  std::string source_filename, source_text;  // C only: the .c file beside the .h
};

EmittedHeader emit_cxx_header(const Analysis& a, const ObserverSpec& spec, const EmitOptions& opt);

// The header that `--method auto` adds: <model>_auto.hpp, aliasing the chosen class.
EmittedHeader emit_cxx_auto_alias(const Analysis& a, const EmittedHeader& chosen,
                                  const std::string& method);

}  // namespace obsynth
