// Front end for the .sym model format (design.md §2): a hand-written lexer and
// recursive-descent parser building GiNaC expressions directly, with real source positions,
// exact rationals for decimals, a function whitelist and a nesting cap.
#pragma once

#include <string>
#include <string_view>

#include "front/model.hpp"

namespace obsynth {

struct ParseLimits {
  int max_nesting = 200;         // parentheses / unary operators
  int max_literal_length = 400;  // digits in a number
  long max_integer_exponent = 1000;
};

// Throws UserError with a file:line:col diagnostic on the first error.
Model parse_model(std::string_view text, const std::string& filename, const ParseLimits& = {});
// Reads the file; an unreadable file is a UserError.
Model load_model(const std::string& path, const ParseLimits& = {});

// A comma-separated list of expressions over the given symbols, with the model syntax
// (command-line inputs such as --u "sin(t)"); `what` names the source in diagnostics.
ExVec parse_expression_list(std::string_view text, const std::string& what,
                            const std::vector<GiNaC::symbol>& symbols, const ParseLimits& = {});

// One exact real number given as text (a command-line value: decimals are exact); a UserError
// "<what>: '<text>' is not a real number" otherwise.
GiNaC::numeric parse_real_number(const std::string& text, const std::string& what);

// Functions a model may call.
bool is_supported_function(const std::string& name);

}  // namespace obsynth
