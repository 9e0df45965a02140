// Observer designs built on the canonical-form analysis (design.md §1):
//  - canonical: Luenberger observer with error dynamics exactly linear in z, realised in z
//    (zh' = A zh + l(u,y) + K (y - y0 - zh_n), xh = T^-1(zh)) or in the original coordinates
//    (xh' = f + g + [tau](xh) (l(u,y) - l(u,h(xh)) + K (y - h(xh)))).
//  - perfect (seed 003 Procedure 1): z as an explicit function of the jets of y and u,
//    xh = T^-1(z).
// Each design is a description of equations; emission and simulation consume it.
#pragma once

#include <ginac/ginac.h>

#include <string>
#include <vector>

#include "analysis/analysis.hpp"

namespace obsynth {

enum class Realisation { z, x };
const char* realisation_name(Realisation r);

struct CanonicalDesignOptions {
  std::vector<GiNaC::numeric> poles;       // empty: default -2, -2.5, -3, ...
  std::optional<Realisation> realisation;  // empty: z when T^-1 is closed-form, else x
};

struct CanonicalDesign {
  std::vector<GiNaC::numeric> poles;
  std::vector<GiNaC::numeric> K;  // K_i = c_{i-1} of prod (s - pole)
  Realisation realisation = Realisation::z;
  std::string realisation_reason;
  bool newton_inverse = false;  // z realisation with T^-1 by runtime Newton
  GiNaC::ex y0;                 // h(x0): z_n = y - y0
  // Symbols of the generated functions' arguments.
  std::vector<GiNaC::symbol> zh;  // z realisation state
  std::vector<GiNaC::symbol> c;   // per-step constant l(u,y) + K (y - y0)
  ExVec z_rhs;                    // zh' in terms of zh and c
  ExVec x_rhs;                    // x realisation: xh' in terms of states, inputs, y
};

// Throws UserError explaining why when the design does not apply.
CanonicalDesign design_canonical(const Analysis& a, const CanonicalDesignOptions& opt);

struct PerfectDesign {
  std::vector<GiNaC::symbol> y_jet;               // y, y', ..., y^(n-1)
  std::vector<std::vector<GiNaC::symbol>> u_jet;  // per input: u, u', ..., u^(n-2)
  ExVec z;                                        // z as functions of the jets
  ExVec x;                                        // T^-1(z(jets)) when T^-1 is closed-form
  bool newton_inverse = false;
  std::vector<std::size_t> input_orders;  // highest derivative of each input actually used
  std::size_t y_order = 0;                // highest derivative of y used
};

PerfectDesign design_perfect(const Analysis& a);

// Real poles -> K with the design.md convention.
std::vector<GiNaC::numeric> gains_from_poles(const std::vector<GiNaC::numeric>& poles);
std::vector<GiNaC::numeric> default_poles(std::size_t n);

}  // namespace obsynth
