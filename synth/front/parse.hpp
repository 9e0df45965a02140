// Front end for the .sym model format (design.md §2): a hand-written lexer and
// recursive-descent parser building GiNaC expressions directly, with real source positions,
// exact rationals for decimals, a function whitelist and a nesting cap.
//
// Line breaks end a statement, except inside brackets (a bracketed list may span lines) and
// after a ',': a line that ends with ',' continues on the next, so any list (states, inputs,
// params, domain, nominal) may be wrapped after a comma:
//   domain x1 in [-2, 2],
//          x2 in [-2, 2]
// A trailing ',' followed by a new statement, or by the end of the file, is a diagnostic at
// the ','.
//
// Names: any identifier but the statement keywords, f g h F and the function names. Names the
// analysis uses for its own symbols (the output y, canonical coordinates z1.., time t) and
// GiNaC's constant names (I, Pi, Euler, Catalan) are the user's to take: the stages' own
// symbols give way (front/fresh_names.hpp) and the emitters escape C/C++ identifiers.
//
// Extensions of design.md §2 (issue 8):
//   h = [ x1 + u ]          outputs may depend on the inputs (direct feedthrough); they must be
//                           defined at the nominal input, where the drift analysis reads them.
//   F = [ x2*log(u), ... ]  a whole field, split at the nominal input u0: f = F(x,u0),
//                           g = F - f (so g(x,u0) = 0). u0 is 0, or the `nominal` line, or,
//                           when F is undefined at u = 0 and no `nominal` line is given, the
//                           middle of the input box; Model::nominal_note says which.
//   nominal u = 1, v = 2    (after `inputs`, only with F) values inside the inputs' domain.
//   option poles = -3, -4   a design parameter, one per line, the value text verbatim as if
//                           given as --poles on the command line (which wins); names are
//                           checked against the design registry when a design is built.
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
