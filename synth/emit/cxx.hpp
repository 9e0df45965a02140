// C++ emission primitives: a naming component that escapes keywords and clashes, a
// precision-aware printer that turns DAG nodes into straight-line code with numbered
// temporaries, and a strict template renderer (all logic stays in C++).
#pragma once

#include <map>
#include <set>
#include <string>
#include <vector>

#include "symbolic/dag.hpp"

namespace obsynth {

enum class Precision { single, double_precision };
// The language of the printed statements: C++ (std:: calls, Scalar(...) literals) or C99
// (sinf/sin by precision, plain suffixed literals). Both read variables through Binding.
enum class Language { cpp, c };
const char* precision_name(Precision p);

// Unique C++ identifiers: keywords, names the generated code uses itself, and names
// already handed out get a trailing underscore (repeated until unique).
class Namer {
 public:
  Namer();
  std::string unique(const std::string& wanted);
  bool taken(const std::string& name) const { return taken_.count(name) > 0; }

 private:
  std::set<std::string> taken_;
};

// An escaped identifier for a model name (for namespaces and file names), a state index or a
// parameter field: keywords and names that standard headers define as macros get a '_'.
std::string cxx_identifier(const std::string& name);
// A parameter field of the C back end: also clear of the C source's own macros N and K.
std::string c_field_identifier(const std::string& name);

// A floating literal of the given precision for an exact value, wrapped as Scalar(...).
std::string scalar_literal(const GiNaC::numeric& v, Precision p);
// The same value as a C99 literal: 2.0, 0.5f (no cast, no integer literals).
std::string c_scalar_literal(const GiNaC::numeric& v, Precision p);
// A table entry (a double computed at synthesis, not an exact value) as a literal of the precision,
// the same text in C and C++: 0.5, 2.0, 0.25f; and a list of them as "a, b, ...".
std::string table_literal(double v, Precision p);
std::string table_literals(const std::vector<double>& values, Precision p);
// A table's entries as initialiser rows of eight, each row indented by `indent`, every entry
// followed by a comma.
std::string table_rows(const std::vector<double>& values, Precision p, const std::string& indent);
// A constant matrix's entries row by row as "a, b, ...", each printed by `literal` (scalar_literal
// or c_scalar_literal): the initialisers of A_cl and B in both back ends.
std::string matrix_literals(const std::vector<std::vector<GiNaC::numeric>>& rows, Precision p,
                            std::string (*literal)(const GiNaC::numeric&, Precision));

struct Assignment {
  std::string target;  // e.g. "out(0)"
  int node;
};

// A variable of the DAG and how the function reads it.
struct Binding {
  std::string local;     // local name in the function (escaped)
  std::string source;    // e.g. "x(0)"
  std::string argument;  // the function parameter the source reads, e.g. "x"
};

struct EmittedCode {
  std::string text;  // statements, one per line, with the given indent
  std::size_t temporaries = 0;
  std::size_t operations = 0;            // arithmetic operations and calls (a size measure)
  std::set<std::string> arguments_read;  // Binding::argument of every variable read
};

// Straight-line statements computing every assignment. Variables used are first read into
// const locals; nodes used more than once become numbered temporaries (t0, t1, ... in
// emission order, which depends only on expression content).
EmittedCode emit_statements(const Dag& dag, const std::vector<Assignment>& outputs,
                            const std::map<std::string, Binding>& bindings, Precision precision,
                            const std::string& indent, Language language = Language::cpp);

// Replaces {{key}} in a template. Every placeholder must be provided and every provided
// key must be used; anything else is an internal error (a bug in a template).
std::string render_template(const std::string& tmpl,
                            const std::map<std::string, std::string>& values);
// render_template with only those of `values` whose placeholder the template has (one table of
// values serves several templates).
std::string render_template_subset(const std::string& tmpl,
                                   const std::map<std::string, std::string>& values);

}  // namespace obsynth
