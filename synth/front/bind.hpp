// Binding free parameters at synthesis time (`--param name=value`): the value is substituted
// into f, g and h and the parameter stops being a run-time field.
#pragma once

#include <string>
#include <vector>

#include "front/model.hpp"

namespace obsynth {

// Each assignment is "name=value" with an exact real value (decimals are exact). Unknown
// names, parameters that already have a value, and values outside the parameter's declared
// domain box are diagnostics.
Model bind_parameters(Model m, const std::vector<std::string>& assignments);

}  // namespace obsynth
