// The parsed model: symbols created exactly once (GiNaC compares symbols by identity),
// vector fields with numeric parameter defaults already substituted.
#pragma once

#include <ginac/ginac.h>

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "front/diagnostics.hpp"

namespace obsynth {

using ExVec = std::vector<GiNaC::ex>;

struct Interval {
  GiNaC::numeric lo, hi;
};

struct Param {
  std::string name;
  GiNaC::symbol symbol;
  std::optional<GiNaC::numeric> value;  // empty: free parameter, kept symbolic
  SourceLoc loc;
};

struct Model {
  std::string name;
  std::string file;
  std::vector<GiNaC::symbol> states;
  std::vector<GiNaC::symbol> inputs;
  std::vector<Param> params;
  ExVec f;                                     // drift, g(x,0) = 0 split off
  ExVec g;                                     // input part, zero at u = 0
  ExVec h;                                     // outputs
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
  // f + g
  ExVec field() const;
};

}  // namespace obsynth
