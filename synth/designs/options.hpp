// Reading design options (strings as given on the command line) into values, with
// diagnostics that name the option.
#pragma once

#include <ginac/ginac.h>

#include <optional>
#include <string>
#include <vector>

#include "designs/spec.hpp"

namespace obsynth {

// A comma-separated list of exact real numbers (decimals are exact); empty when not given.
std::vector<GiNaC::numeric> real_list_option(const DesignOptions& o, const std::string& name);
// One exact real number, if given.
std::optional<GiNaC::numeric> real_option(const DesignOptions& o, const std::string& name);
// One of the allowed words, if given.
std::optional<std::string> choice_option(const DesignOptions& o, const std::string& name,
                                         const std::vector<std::string>& allowed);

}  // namespace obsynth
