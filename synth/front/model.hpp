// The parsed model: symbols created exactly once (GiNaC compares symbols by identity),
// vector fields with numeric parameter defaults already substituted.
#pragma once

#include <ginac/ginac.h>

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "foundation/diagnostics.hpp"
#include "foundation/expr.hpp"

namespace obsynth {

struct Param {
  std::string name;
  GiNaC::symbol symbol;
  std::optional<GiNaC::numeric> value;  // empty: free parameter, kept symbolic
  SourceLoc loc;
};

// A design parameter given in the model file: `option <name> = <value text>`; the value text
// is passed verbatim, as if given on the command line as --<name>.
struct ModelOption {
  std::string name;
  std::string value;
  SourceLoc loc;  // of the name
};

struct Model {
  std::string name;
  std::string file;
  std::vector<GiNaC::symbol> states;
  std::vector<GiNaC::symbol> inputs;
  std::vector<Param> params;
  ExVec f;  // drift, g(x,u0) = 0 split off
  ExVec g;  // input part, zero at u = u0 (0 unless nominal)
  ExVec h;  // outputs h(x) or h(x,u) (direct feedthrough)
  // A separable feedthrough y = h0(x) + k(u) is analysed as h = h0(x) with output_offset = k(u)
  // (set by analyse(), empty otherwise): every design then observes y - k(u).
  ExVec output_offset;
  // The nominal input u0 (one value per input) at which a field given as `F` was split:
  // f = F(x,u0), g = F(x,u) - F(x,u0). Empty: u0 = 0 (design.md §1). nominal_note says how u0
  // was chosen (a `nominal` line, or automatically because F is undefined at u = 0).
  std::vector<GiNaC::numeric> nominal;
  std::string nominal_note;
  std::vector<ModelOption> options;            // `option` lines, in file order
  std::map<std::string, Interval> domain;      // states, inputs and free parameters
  std::map<std::string, SourceLoc> locations;  // where f, g, h, ... were given

  std::size_t n() const { return states.size(); }
  std::size_t m() const { return inputs.size(); }
  std::size_t p() const { return h.size(); }

  // Free parameters (no numeric default): constants in the analysis.
  std::vector<GiNaC::symbol> free_params() const;
  // States, inputs and free parameters, in declaration order.
  std::vector<GiNaC::symbol> all_symbols() const;
  // The sampling box for a symbol: its domain, else the default [-2, 2] (states, inputs)
  // or [1/2, 2] (free parameters).
  Interval box(const GiNaC::symbol& s) const;
  // Those boxes by name, for sampling (states, inputs and free parameters).
  SampleBoxes sample_boxes() const;
  // f + g
  ExVec field() const;
  // Some output depends on an input (y = h(x,u)); h0(x) + k(u) split off does not count.
  bool feedthrough() const;
  // The measured outputs: h, plus output_offset when the feedthrough was split off.
  ExVec measured_outputs() const;
  // u -> u0 (0 when no nominal input was set).
  GiNaC::exmap nominal_inputs() const;
};

}  // namespace obsynth
