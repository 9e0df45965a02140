// A value of a symbolic expression at a point, by GiNaC's evalf at 30 digits, printed with
// 17 significant digits: the reference generators' common output format.
#pragma once

#include <fmt/format.h>
#include <ginac/ginac.h>

#include <stdexcept>
#include <string>

#include "symbolic/zero_test.hpp"

namespace obsynth::testing {

inline std::string reference_value(const GiNaC::ex& e, const GiNaC::exmap& at) {
  DigitsGuard g(30);
  const GiNaC::ex v = GiNaC::evalf(e.subs(at));
  if (!GiNaC::is_a<GiNaC::numeric>(v)) throw std::runtime_error("reference: value not numeric");
  return fmt::format("{:.17e}", GiNaC::ex_to<GiNaC::numeric>(v).to_double());
}

}  // namespace obsynth::testing
