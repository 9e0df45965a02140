// Deterministic printing of expressions. GiNaC's own output order depends on hash values
// that change between runs, so operands are ordered here by their printed text.
// The plain form reads back through GiNaC's parser to the same expression.
#pragma once

#include <ginac/ginac.h>

#include <string>
#include <vector>

namespace obsynth {

std::string to_string(const GiNaC::ex& e);
std::string to_latex(const GiNaC::ex& e);
std::vector<std::string> to_strings(const std::vector<GiNaC::ex>& v);

}  // namespace obsynth
