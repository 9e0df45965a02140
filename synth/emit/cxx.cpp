#include "emit/cxx.hpp"

#include <fmt/format.h>

#include <cctype>
#include <cmath>
#include <functional>
#include <limits>

#include "foundation/diagnostics.hpp"

namespace obsynth {

const char* precision_name(Precision p) {
  return p == Precision::single ? "float" : "double";
}

namespace {

const char* const kCxxKeywords[] = {"alignas",       "alignof",     "and",
                                    "and_eq",        "asm",         "auto",
                                    "bitand",        "bitor",       "bool",
                                    "break",         "case",        "catch",
                                    "char",          "char8_t",     "char16_t",
                                    "char32_t",      "class",       "compl",
                                    "concept",       "const",       "consteval",
                                    "constexpr",     "constinit",   "const_cast",
                                    "continue",      "co_await",    "co_return",
                                    "co_yield",      "decltype",    "default",
                                    "delete",        "do",          "double",
                                    "dynamic_cast",  "else",        "enum",
                                    "explicit",      "export",      "extern",
                                    "false",         "float",       "for",
                                    "friend",        "goto",        "if",
                                    "inline",        "int",         "long",
                                    "mutable",       "namespace",   "new",
                                    "noexcept",      "not",         "not_eq",
                                    "nullptr",       "operator",    "or",
                                    "or_eq",         "private",     "protected",
                                    "public",        "register",    "reinterpret_cast",
                                    "requires",      "return",      "short",
                                    "signed",        "sizeof",      "static",
                                    "static_assert", "static_cast", "struct",
                                    "switch",        "template",    "this",
                                    "thread_local",  "throw",       "true",
                                    "try",           "typedef",     "typeid",
                                    "typename",      "union",       "unsigned",
                                    "using",         "virtual",     "void",
                                    "volatile",      "wchar_t",     "while",
                                    "xor",           "xor_eq",      "final",
                                    "override",      "import",      "module"};
// Names that standard headers of the generated code may define as macros, C keywords, and the
// template parameter Scalar (a parameter field named Scalar would shadow it): never an
// identifier taken from the model.
const char* const kReservedIdentifiers[] = {
    "restrict", "Scalar", "NAN", "INFINITY", "HUGE_VAL", "HUGE_VALF", "errno", "assert", "EOF",
    "NULL", "isfinite", "isnan", "isinf", "signbit", "fpclassify", "math_errhandling",
    // <cmath>'s (POSIX) constants, macros in glibc
    "M_E", "M_LOG2E", "M_LOG10E", "M_LN2", "M_LN10", "M_PI", "M_PI_2", "M_PI_4", "M_1_PI", "M_2_PI",
    "M_2_SQRTPI", "M_SQRT2", "M_SQRT1_2", "FP_NAN", "FP_INFINITE", "FP_ZERO", "FP_NORMAL",
    "FP_SUBNORMAL", "HUGE_VALL", "FLT_EVAL_METHOD", "MATH_ERRNO", "MATH_ERREXCEPT", "isnormal",
    "isgreater", "isless", "isunordered", "FP_FAST_FMA", "FP_ILOGB0"};
// Names the generated code itself uses in observer classes and functions; "N" and "K" are
// macros of the C source, "I" is <complex.h>'s, sinf ... the float calls of the C back end.
const char* const kGeneratedNames[] = {
    "N",     "I",      "sinf",   "cosf",     "tanf",   "expf",   "logf",  "sqrtf",   "tanhf",
    "atanf", "powf",   "fabsf",  "atanhf",   "Scalar", "Eigen",  "std",   "obsynth", "State",
    "Input", "Output", "Matrix", "Status",   "dt",     "n",      "m",     "p",       "x",
    "u",     "y",      "z",      "out",      "tau",    "xh",     "zh",    "dz",      "dx",
    "K",     "y0",     "jet",    "ujet",     "main",   "assert", "errno", "NAN",     "INFINITY",
    "sin",   "cos",    "tan",    "exp",      "log",    "sqrt",   "tanh",  "atan",    "atanh",
    "pow",   "abs",    "fabs",   "isfinite", "w",      "c",      "yj"};

bool is_temporary_name(const std::string& s) {
  if (s.size() < 2 || s[0] != 't') return false;
  for (std::size_t i = 1; i < s.size(); ++i)
    if (!std::isdigit(static_cast<unsigned char>(s[i]))) return false;
  return true;
}

}  // namespace

Namer::Namer() {
  for (const char* k : kCxxKeywords) taken_.insert(k);
  for (const char* k : kReservedIdentifiers) taken_.insert(k);
  for (const char* k : kGeneratedNames) taken_.insert(k);
}

std::string Namer::unique(const std::string& wanted) {
  std::string s = cxx_identifier(wanted);
  // Temporaries t0, t1, ... and identifiers reserved to the implementation.
  while (taken_.count(s) || is_temporary_name(s) || (s.size() > 1 && s[0] == '_')) s += "_";
  taken_.insert(s);
  return s;
}

std::string cxx_identifier(const std::string& name) {
  std::string s;
  for (char c : name) s += (std::isalnum(static_cast<unsigned char>(c)) || c == '_') ? c : '_';
  if (s.empty() || std::isdigit(static_cast<unsigned char>(s[0]))) s = "m_" + s;
  if (s.find("__") != std::string::npos) {
    std::string t;
    for (char c : s)
      if (!(c == '_' && !t.empty() && t.back() == '_')) t += c;
    s = t;
  }
  for (const char* k : kCxxKeywords)
    if (s == k) return s + "_";
  for (const char* k : kReservedIdentifiers)
    if (s == k) return s + "_";
  return s;
}

std::string c_field_identifier(const std::string& name) {
  const std::string s = cxx_identifier(name);
  return s == "N" || s == "K" ? s + "_" : s;
}

namespace {

// The constant as a double that the chosen precision represents: a value beyond its range
// (or below its smallest normal number, where float code would flush it) is a user error, never
// an "inf" literal that does not compile or a silent zero.
double representable(const GiNaC::numeric& v, Precision p) {
  const double d = v.to_double();
  const bool single = p == Precision::single;
  const double max = single ? 3.4028234663852886e38 : std::numeric_limits<double>::max();
  const double min = single ? 1.1754943508222875e-38 : std::numeric_limits<double>::min();
  const double a = std::abs(d);
  if (std::isfinite(d) && a <= max && (a == 0 || a >= min)) return d;
  throw UserError(SourceLoc{},
                  fmt::format("the generated code needs the constant {:.6g}, which {} cannot "
                              "represent (its normal range is [{:.3g}, {:.3g}]){}",
                              d, precision_name(p), min, max,
                              single ? "; use --precision double" : "; rescale the model"));
}

}  // namespace

std::string scalar_literal(const GiNaC::numeric& v, Precision p) {
  if (v.is_integer() && GiNaC::abs(v) < GiNaC::numeric(1L << 24))
    return fmt::format("Scalar({})", v.to_long());
  const double d = representable(v, p);
  if (p == Precision::single) {
    std::string s = fmt::format("{:.9g}", static_cast<float>(d));
    if (s.find_first_of(".e") == std::string::npos) s += ".0";
    return "Scalar(" + s + "f)";
  }
  std::string s = fmt::format("{:.17g}", d);
  if (s.find_first_of(".e") == std::string::npos) s += ".0";
  return "Scalar(" + s + ")";
}

std::string c_scalar_literal(const GiNaC::numeric& v, Precision p) {
  const double d = representable(v, p);
  std::string s = p == Precision::single ? fmt::format("{:.9g}", static_cast<float>(d))
                                         : fmt::format("{:.17g}", d);
  if (s.find_first_of(".e") == std::string::npos) s += ".0";
  return p == Precision::single ? s + "f" : s;
}

std::string table_literal(double v, Precision p) {
  std::string t = p == Precision::single ? fmt::format("{:.9g}", static_cast<float>(v))
                                         : fmt::format("{:.17g}", v);
  if (t.find_first_of(".en") == std::string::npos) t += ".0";
  return p == Precision::single ? t + "f" : t;
}

std::string table_literals(const std::vector<double>& values, Precision p) {
  std::vector<std::string> v;
  for (const double x : values) v.push_back(table_literal(x, p));
  return fmt::format("{}", fmt::join(v, ", "));
}

std::string table_rows(const std::vector<double>& values, Precision p, const std::string& indent) {
  std::string out;
  for (std::size_t i = 0; i < values.size(); ++i) {
    out += i % 8 == 0 ? indent : " ";
    out += table_literal(values[i], p) + ",";
    if (i % 8 == 7 || i + 1 == values.size()) out += "\n";
  }
  return out;
}

std::string matrix_literals(const std::vector<std::vector<GiNaC::numeric>>& rows, Precision p,
                            std::string (*literal)(const GiNaC::numeric&, Precision)) {
  std::vector<std::string> v;
  for (const auto& row : rows)
    for (const auto& q : row) v.push_back(literal(q, p));
  return fmt::format("{}", fmt::join(v, ", "));
}

namespace {

enum Prec { p_sum = 1, p_product = 2, p_unary = 3, p_atom = 4 };

struct Text {
  std::string s;
  int prec;
};

class StatementEmitter {
 public:
  StatementEmitter(const Dag& dag, const std::map<std::string, Binding>& bindings,
                   Precision precision, const std::string& indent, Language language)
      : dag_(dag),
        bindings_(bindings),
        precision_(precision),
        indent_(indent),
        language_(language) {}

  EmittedCode run(const std::vector<Assignment>& outputs) {
    count_uses(outputs);
    std::string body;
    for (const auto& a : outputs) {
      const Text t = expr(a.node);
      assign_.push_back(fmt::format("{}{} = {};\n", indent_, a.target, t.s));
    }
    EmittedCode code;
    for (const auto& [name, b] : used_vars_) {
      code.text += fmt::format("{}const Scalar {} = {};\n", indent_, b.local, b.source);
      code.arguments_read.insert(b.argument);
    }
    for (const auto& s : temps_) code.text += s;
    for (const auto& s : assign_) code.text += s;
    code.temporaries = temp_count_;
    code.operations = operations_;
    return code;
  }

 private:
  const Dag& dag_;
  const std::map<std::string, Binding>& bindings_;
  Precision precision_;
  std::string indent_;
  Language language_;

  std::string literal(const GiNaC::numeric& v) const {
    return language_ == Language::c ? c_scalar_literal(v, precision_)
                                    : scalar_literal(v, precision_);
  }
  // A math function's name: std::sin in C++, sin or sinf (by precision) in C.
  std::string math(const std::string& name) const {
    if (language_ == Language::cpp) return "std::" + name;
    const std::string c_name = name == "abs" ? "fabs" : name;
    return precision_ == Precision::single ? c_name + "f" : c_name;
  }
  std::map<int, int> uses_;
  std::map<int, Text> done_;
  std::map<std::string, Binding> used_vars_;
  std::vector<std::string> temps_, assign_;
  std::size_t temp_count_ = 0, operations_ = 0;

  const Node& node(int id) const { return dag_.node(id); }
  static bool is_leaf(const Node& n) {
    return n.op == NodeOp::constant || n.op == NodeOp::variable;
  }

  void count_uses(const std::vector<Assignment>& outputs) {
    std::set<int> seen;
    std::function<void(int)> visit = [&](int id) {
      ++uses_[id];
      if (!seen.insert(id).second) return;
      for (int a : node(id).args) visit(a);
    };
    for (const auto& a : outputs) visit(a.node);
  }

  static std::string wrap(const Text& t, int min_prec) {
    return t.prec >= min_prec ? t.s : "(" + t.s + ")";
  }

  Text materialise(int id, Text t) {
    const Node& n = node(id);
    if (!is_leaf(n) && (uses_[id] > 1 || t.s.size() > 160)) {
      const std::string name = fmt::format("t{}", temp_count_++);
      temps_.push_back(fmt::format("{}const Scalar {} = {};\n", indent_, name, t.s));
      t = {name, p_atom};
    }
    done_[id] = t;
    return t;
  }

  // Operand of a repeated product: must be a name or literal.
  Text atom_operand(int id) {
    Text t = expr(id);
    if (t.prec == p_atom && t.s.find_first_of(" (") == std::string::npos) return t;
    const std::string name = fmt::format("t{}", temp_count_++);
    temps_.push_back(fmt::format("{}const Scalar {} = {};\n", indent_, name, t.s));
    Text named{name, p_atom};
    done_[id] = named;
    return named;
  }

  // A sum's text, negative terms as subtractions; `negated` prints -(a - b) as -a + b, which
  // is exact (IEEE negation commutes with rounding) and spares the parentheses.
  Text sum_text(const Node& n, bool negated) {
    std::string s;
    for (std::size_t i = 0; i < n.args.size(); ++i) {
      const Node& a = node(n.args[i]);
      bool minus = negated;
      Text t;
      if (a.op == NodeOp::constant && a.value.is_negative()) {
        minus = !minus;
        t = {literal(GiNaC::abs(a.value)), p_atom};
      } else if (a.op == NodeOp::neg) {
        minus = !minus;
        t = expr(a.args[0]);
      } else {
        t = expr(n.args[i]);
      }
      if (i == 0)
        s = minus ? "-" + wrap(t, p_unary) : t.s;
      else
        s += (minus ? " - " : " + ") + wrap(t, p_product);
      if (i > 0 || minus) ++operations_;
    }
    return {s, p_sum};
  }

  Text expr(int id) {
    auto d = done_.find(id);
    if (d != done_.end()) return d->second;
    const Node& n = node(id);
    switch (n.op) {
      case NodeOp::constant: {
        const GiNaC::numeric& v = n.value;
        const std::string lit = literal(GiNaC::abs(v));
        return done_[id] = v.is_negative() ? Text{"-" + lit, p_unary} : Text{lit, p_atom};
      }
      case NodeOp::variable: {
        auto it = bindings_.find(n.name);
        OBSYNTH_ASSERT(it != bindings_.end(), "no binding for variable " + n.name);
        used_vars_.emplace(n.name, it->second);
        return done_[id] = Text{it->second.local, p_atom};
      }
      case NodeOp::add:
        return materialise(id, sum_text(n, false));
      case NodeOp::mul: {
        std::string s;
        for (std::size_t i = 0; i < n.args.size(); ++i) {
          s += (i ? " * " : "") + wrap(expr(n.args[i]), p_unary);
          if (i) ++operations_;
        }
        return materialise(id, {s, p_product});
      }
      case NodeOp::div: {
        ++operations_;
        const Text a = expr(n.args[0]), b = expr(n.args[1]);
        return materialise(id, {wrap(a, p_product) + " / " + wrap(b, p_unary), p_product});
      }
      case NodeOp::neg: {
        const int arg = n.args[0];
        if (node(arg).op == NodeOp::add && !done_.count(arg) && uses_[arg] == 1)
          return materialise(id, sum_text(node(arg), true));
        ++operations_;
        return materialise(id, {"-" + wrap(expr(arg), p_unary), p_unary});
      }
      case NodeOp::pow_int: {
        const Text b = atom_operand(n.args[0]);
        long k = n.exponent;
        OBSYNTH_ASSERT(k >= 2, "pow_int exponent below 2");
        if (k <= 4) {
          std::string s = b.s;
          for (long i = 1; i < k; ++i) s += " * " + b.s;
          operations_ += static_cast<std::size_t>(k - 1);
          return materialise(id, {s, p_product});
        }
        // Square and multiply with named squares.
        std::string result;
        std::string sq = b.s;
        while (k > 0) {
          if (k & 1) result = result.empty() ? sq : result + " * " + sq;
          k >>= 1;
          if (k) {
            const std::string name = fmt::format("t{}", temp_count_++);
            temps_.push_back(fmt::format("{}const Scalar {} = {} * {};\n", indent_, name, sq, sq));
            sq = name;
            ++operations_;
          }
        }
        return materialise(id, {result, p_product});
      }
      case NodeOp::sqrt:
        ++operations_;
        return materialise(id, {math("sqrt") + "(" + expr(n.args[0]).s + ")", p_atom});
      case NodeOp::pow_real:
        ++operations_;
        return materialise(
            id,
            {fmt::format("{}({}, {})", math("pow"), expr(n.args[0]).s, literal(n.value)), p_atom});
      case NodeOp::call:
        ++operations_;
        return materialise(id, {fmt::format("{}({})", math(n.name), expr(n.args[0]).s), p_atom});
    }
    OBSYNTH_ASSERT(false, "unknown node kind");
  }
};

}  // namespace

EmittedCode emit_statements(const Dag& dag, const std::vector<Assignment>& outputs,
                            const std::map<std::string, Binding>& bindings, Precision precision,
                            const std::string& indent, Language language) {
  return StatementEmitter(dag, bindings, precision, indent, language).run(outputs);
}

std::string render_template(const std::string& tmpl,
                            const std::map<std::string, std::string>& values) {
  std::string out;
  std::set<std::string> used;
  std::size_t pos = 0;
  for (;;) {
    const std::size_t open = tmpl.find("{{", pos);
    if (open == std::string::npos) {
      out += tmpl.substr(pos);
      break;
    }
    const std::size_t close = tmpl.find("}}", open);
    OBSYNTH_ASSERT(close != std::string::npos, "unterminated placeholder in template");
    out += tmpl.substr(pos, open - pos);
    const std::string key = tmpl.substr(open + 2, close - open - 2);
    auto it = values.find(key);
    OBSYNTH_ASSERT(it != values.end(), "template placeholder without a value: " + key);
    out += it->second;
    used.insert(key);
    pos = close + 2;
  }
  for (const auto& [k, v] : values)
    OBSYNTH_ASSERT(used.count(k), "template value never used: " + k);
  return out;
}

std::string render_template_subset(const std::string& tmpl,
                                   const std::map<std::string, std::string>& values) {
  std::map<std::string, std::string> used;
  for (const auto& [k, v] : values)
    if (tmpl.find("{{" + k + "}}") != std::string::npos) used.emplace(k, v);
  return render_template(tmpl, used);
}

}  // namespace obsynth
