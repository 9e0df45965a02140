// Writing a function of x as a function of the output y = h(x), when it is one.
#pragma once

#include <ginac/ginac.h>

#include <optional>

#include "symbolic/lie.hpp"
#include "symbolic/poly.hpp"
#include "symbolic/zero_test.hpp"

namespace obsynth {

// e(x) written as a function of y = h(x) alone, if it is one (h must be solvable for some
// state); nullopt otherwise.
std::optional<GiNaC::ex> express_in_output(const GiNaC::ex& e, const GiNaC::ex& h, const Symbols& x,
                                           const GiNaC::symbol& y, const ExVec& base_point,
                                           const SampleBoxes& boxes);

// e(x) written as a function of y = h(x) for p outputs: h_1 = y_1, h_2 = y_2, ... solved in
// turn, each for a new state (as above); nullopt when e is not such a function.
std::optional<GiNaC::ex> express_in_outputs(const GiNaC::ex& e, const ExVec& h, const Symbols& x,
                                            const std::vector<GiNaC::symbol>& y,
                                            const ExVec& base_point, const SampleBoxes& boxes);

// The same for ring elements, with a verdict on p(x) = A(h(x)). When h = c x_k + b(x) with a
// constant c != 0 and b free of x_k, A is p restricted to the line through x0 along e_k, and
// the identity is checked in the ring (proved when it holds there).
class OutputFunction {
 public:
  OutputFunction(const PolyRing& ring, const GiNaC::ex& h, const Symbols& x, GiNaC::symbol y,
                 ExVec base_point, SampleBoxes boxes, ZeroTestOptions zero);
  struct Result {
    GiNaC::ex value;  // in y (and inputs, parameters)
    ZeroVerdict verdict = ZeroVerdict::proved;
  };
  std::optional<Result> operator()(const Poly& p) const;

 private:
  const PolyRing& ring_;
  GiNaC::ex h_;
  Symbols x_;
  GiNaC::symbol y_;
  ExVec base_point_;
  SampleBoxes boxes_;
  ZeroTestOptions zero_;
  std::optional<GiNaC::exmap> line_;  // x on the line, in terms of y
};

}  // namespace obsynth
