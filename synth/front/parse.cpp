#include "front/parse.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <fstream>
#include <set>
#include <sstream>

#include "symbolic/expr_print.hpp"
#include "symbolic/symbolic.hpp"
#include "symbolic/zero_test.hpp"

namespace obsynth {

using GiNaC::ex;
using GiNaC::numeric;

namespace {

// Largest exact number (in bits) a model may produce when it is built or evaluated exactly at
// a rational point; beyond this, exact arithmetic (gcds of huge integers) takes seconds to hours.
constexpr long kMaxExactBits = 1L << 18;       // about 79,000 decimal digits
constexpr long kMaxEvaluationBits = 1L << 24;  // exact evaluation of whole expressions

const char* const kFunctions[] = {"sin", "cos", "tan", "exp", "log", "sqrt", "tanh", "atan"};
const char* const kKeywords[] = {"model", "states", "inputs", "params",  "f",     "g",
                                 "h",     "F",      "domain", "nominal", "option"};
std::size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> prev(b.size() + 1), cur(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) prev[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    cur[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j)
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (a[i - 1] != b[j - 1])});
    std::swap(prev, cur);
  }
  return prev[b.size()];
}

std::string suggestion(const std::string& word, const std::vector<std::string>& candidates) {
  std::string best;
  std::size_t best_d = 3;
  for (const auto& c : candidates) {
    const std::size_t d = edit_distance(word, c);
    if (d < best_d && d < std::max<std::size_t>(2, c.size() / 2 + 1)) {
      best_d = d;
      best = c;
    }
  }
  return best.empty() ? "" : fmt::format("; did you mean '{}'?", best);
}

enum class Tok { ident, number, op, newline, end };

struct Token {
  Tok kind;
  std::string text;
  int line, col;
};

class Lexer {
 public:
  Lexer(std::string_view src, const std::string& file, const ParseLimits& lim)
      : src_(src), file_(file), lim_(lim) {}

  std::vector<Token> run() {
    std::vector<Token> out;
    std::vector<Token> open;  // the brackets not yet closed
    while (pos_ < src_.size()) {
      const char c = src_[pos_];
      if (c == '#') {
        while (pos_ < src_.size() && src_[pos_] != '\n') advance();
        continue;
      }
      if (c == '\n') {
        // Newlines inside brackets, and after a ',', continue the statement.
        if (open.empty() && !out.empty() && out.back().kind != Tok::newline &&
            !ends_with_comma(out))
          out.push_back({Tok::newline, "\\n", line_, col_});
        advance();
        continue;
      }
      if (c == ' ' || c == '\t' || c == '\r') {
        advance();
        continue;
      }
      const int l = line_, k = col_;
      if (std::isalpha(static_cast<unsigned char>(c)) || c == '_') {
        std::string s;
        while (pos_ < src_.size() &&
               (std::isalnum(static_cast<unsigned char>(src_[pos_])) || src_[pos_] == '_'))
          s += advance();
        out.push_back({Tok::ident, s, l, k});
        continue;
      }
      if (std::isdigit(static_cast<unsigned char>(c)) ||
          (c == '.' && pos_ + 1 < src_.size() &&
           std::isdigit(static_cast<unsigned char>(src_[pos_ + 1])))) {
        out.push_back(number(l, k));
        continue;
      }
      if (std::string_view("+-*/^()[],=").find(c) != std::string_view::npos) {
        advance();
        match_bracket(c, l, k, open);
        out.push_back({Tok::op, std::string(1, c), l, k});
        continue;
      }
      throw UserError({file_, l, k},
                      std::isprint(static_cast<unsigned char>(c))
                          ? fmt::format("unexpected character '{}'", c)
                          : fmt::format("unexpected byte 0x{:02x}", static_cast<unsigned char>(c)));
    }
    if (!open.empty())
      throw UserError({file_, open.back().line, open.back().col},
                      fmt::format("unbalanced '{}': never closed", open.back().text));
    if (!out.empty() && out.back().kind != Tok::newline)
      out.push_back({Tok::newline, "\\n", line_, col_});
    out.push_back({Tok::end, "", line_, col_});
    return out;
  }

 private:
  static bool ends_with_comma(const std::vector<Token>& out) {
    return !out.empty() && out.back().kind == Tok::op && out.back().text == ",";
  }

  // A number literal at (l, k): digits and dots, then an exponent if one follows.
  Token number(int l, int k) {
    std::string s;
    while (pos_ < src_.size() &&
           (std::isdigit(static_cast<unsigned char>(src_[pos_])) || src_[pos_] == '.'))
      s += advance();
    if (pos_ < src_.size() && (src_[pos_] == 'e' || src_[pos_] == 'E')) {
      std::size_t q = pos_ + 1;
      if (q < src_.size() && (src_[q] == '+' || src_[q] == '-')) ++q;
      if (q < src_.size() && std::isdigit(static_cast<unsigned char>(src_[q]))) {
        while (pos_ < q) s += advance();
        while (pos_ < src_.size() && std::isdigit(static_cast<unsigned char>(src_[pos_])))
          s += advance();
      }
    }
    if (static_cast<int>(s.size()) > lim_.max_literal_length)
      throw UserError({file_, l, k}, fmt::format("number literal longer than {} characters",
                                                 lim_.max_literal_length));
    return {Tok::number, s, l, k};
  }

  // Tracks brackets: an opening one is pushed on open, a closing one must match its top.
  void match_bracket(char c, int l, int k, std::vector<Token>& open) const {
    if (c == '(' || c == '[') {
      open.push_back({Tok::op, std::string(1, c), l, k});
    } else if (c == ')' || c == ']') {
      const char want = c == ')' ? '(' : '[';
      if (open.empty())
        throw UserError({file_, l, k}, fmt::format("unbalanced '{}': no matching '{}'", c, want));
      if (open.back().text[0] != want)
        throw UserError({file_, l, k},
                        fmt::format("'{}' closes the '{}' opened at {}:{}", c, open.back().text,
                                    open.back().line, open.back().col));
      open.pop_back();
    }
  }

  char advance() {
    const char c = src_[pos_++];
    if (c == '\n') {
      ++line_;
      col_ = 1;
    } else {
      ++col_;
    }
    return c;
  }
  std::string_view src_;
  const std::string& file_;
  const ParseLimits& lim_;
  std::size_t pos_ = 0;
  int line_ = 1, col_ = 1;
};

numeric parse_number(const std::string& s, const SourceLoc& loc) {
  // Exact rational: mantissa digits over a power of ten, times 10^exponent.
  std::string mant = s, expo;
  const auto epos = s.find_first_of("eE");
  if (epos != std::string::npos) {
    mant = s.substr(0, epos);
    expo = s.substr(epos + 1);
  }
  if (std::count(mant.begin(), mant.end(), '.') > 1)
    throw UserError(loc, fmt::format("malformed number '{}'", s));
  std::string digits;
  long frac = 0;
  bool after = false;
  for (char c : mant) {
    if (c == '.') {
      after = true;
      continue;
    }
    digits += c;
    if (after) ++frac;
  }
  if (digits.empty()) throw UserError(loc, fmt::format("malformed number '{}'", s));
  long e10 = -frac;
  if (!expo.empty()) {
    if (expo.size() > 5) throw UserError(loc, fmt::format("exponent of '{}' is out of range", s));
    e10 += std::stol(expo);
  }
  if (std::labs(e10) > 400)
    throw UserError(loc, fmt::format("exponent of '{}' is out of range", s));
  numeric v(digits.c_str());
  return v * numeric(10).power(numeric(e10));
}

// `option <name> = <value text>` lines are taken out before lexing (the value text is passed
// verbatim, as if given on the command line, so it is not tokenised); the line is blanked so
// that every other position stays where it was.
std::vector<ModelOption> take_option_lines(std::string& src, const std::string& file) {
  std::vector<ModelOption> out;
  std::size_t start = 0;
  int line = 1;
  int depth = 0;           // inside a bracketed list an "option" word is an expression
  bool continues = false;  // so it is after a line that ends with ',' (the list goes on)
  while (start <= src.size()) {
    std::size_t end = src.find('\n', start);
    if (end == std::string::npos) end = src.size();
    std::size_t i = start;
    while (i < end && (src[i] == ' ' || src[i] == '\t')) ++i;
    const bool is_option = depth == 0 && !continues && end - i > 6 &&
                           src.compare(i, 6, "option") == 0 &&
                           (src[i + 6] == ' ' || src[i + 6] == '\t');
    if (is_option) {
      std::size_t stop = src.find('#', i);
      if (stop == std::string::npos || stop > end) stop = end;
      std::size_t k = i + 6;
      while (k < stop && (src[k] == ' ' || src[k] == '\t')) ++k;
      const int name_col = static_cast<int>(k - start) + 1;
      std::size_t name_end = k;
      while (name_end < stop && (std::isalnum(static_cast<unsigned char>(src[name_end])) ||
                                 src[name_end] == '_' || src[name_end] == '-'))
        ++name_end;
      const SourceLoc loc{file, line, name_col};
      if (name_end == k)
        throw UserError(loc, "expected an option name after 'option' (option NAME = VALUE)");
      const std::string name = src.substr(k, name_end - k);
      std::size_t e = name_end;
      while (e < stop && (src[e] == ' ' || src[e] == '\t')) ++e;
      if (e >= stop || src[e] != '=')
        throw UserError(
            {file, line, static_cast<int>(e - start) + 1},
            fmt::format("expected '=' after the option name '{}' (option {} = VALUE)", name, name));
      std::string value = src.substr(e + 1, stop - e - 1);
      const auto first = value.find_first_not_of(" \t\r");
      const auto last = value.find_last_not_of(" \t\r");
      value = first == std::string::npos ? "" : value.substr(first, last - first + 1);
      if (value.empty())
        throw UserError({file, line, static_cast<int>(e - start) + 1},
                        fmt::format("option '{}' has no value after '='", name));
      for (const auto& o : out)
        if (o.name == name)
          throw UserError(loc, fmt::format("duplicate option '{}': already given at {}:{}", name,
                                           o.loc.line, o.loc.col));
      out.push_back({name, value, loc});
      for (std::size_t q = start; q < end; ++q) src[q] = ' ';
    } else {
      char last = 0;  // the line's last character outside comments and blanks
      for (std::size_t q = i; q < end; ++q) {
        if (src[q] == '#') break;
        if (src[q] == '[' || src[q] == '(') ++depth;
        if ((src[q] == ']' || src[q] == ')') && depth > 0) --depth;
        if (src[q] != ' ' && src[q] != '\t' && src[q] != '\r') last = src[q];
      }
      if (last) continues = last == ',';
    }
    start = end + 1;
    ++line;
  }
  return out;
}

struct Declared {
  enum Kind { state, input, param } kind;
  GiNaC::symbol sym;
  SourceLoc loc;
};

const char* kind_name(Declared::Kind k) {
  switch (k) {
    case Declared::state:
      return "state";
    case Declared::input:
      return "input";
    case Declared::param:
      return "parameter";
  }
  return "symbol";
}

class Parser {
 public:
  Parser(std::vector<Token> toks, std::string file, const ParseLimits& lim)
      : toks_(std::move(toks)), file_(std::move(file)), lim_(lim) {}

  // A comma-separated list of expressions over the given symbols (e.g. --u "sin(t)").
  ExVec standalone_list(const std::vector<GiNaC::symbol>& symbols) {
    for (const auto& sym : symbols)
      names_.emplace(sym.get_name(), Declared{Declared::state, sym, SourceLoc{file_, 0, 0}});
    ExVec out;
    if (peek().kind == Tok::end) fail(peek(), "expected an expression");
    do {
      out.push_back(expression());
    } while (accept_op(','));
    if (peek().kind == Tok::newline) ++i_;
    if (peek().kind != Tok::end)
      fail(peek(), fmt::format("unexpected {} after the expression", describe(peek())));
    const SampleBoxes boxes;
    check_divisors(boxes);
    return out;
  }

  Model run() {
    model_.file = file_;
    if (toks_.size() == 1)
      throw UserError({file_, 1, 1}, "empty model: expected 'model', 'states', 'f' and 'h'");
    while (peek().kind != Tok::end) statement();
    return finish();
  }

 private:
  std::vector<Token> toks_;
  std::string file_;
  const ParseLimits& lim_;
  std::size_t i_ = 0;
  Model model_;
  std::map<std::string, Declared> names_;
  std::vector<std::pair<ex, SourceLoc>> divisors_;
  std::optional<ExVec> f_, g_, h_, F_;
  struct NominalValue {
    GiNaC::symbol input;
    numeric value;
    SourceLoc loc;
  };
  std::optional<std::vector<NominalValue>> nominal_;
  SourceLoc nominal_loc_;
  int depth_ = 0;

  const Token& peek() const { return toks_[i_]; }
  const Token& next() { return toks_[i_++]; }
  SourceLoc loc(const Token& t) const { return {file_, t.line, t.col}; }
  [[noreturn]] void fail(const Token& t, const std::string& msg) const {
    throw UserError(loc(t), msg);
  }

  static std::string describe(const Token& t) {
    switch (t.kind) {
      case Tok::newline:
        return "end of line";
      case Tok::end:
        return "end of file";
      default:
        return "'" + t.text + "'";
    }
  }

  bool accept_op(char c) {
    if (peek().kind == Tok::op && peek().text[0] == c) {
      ++i_;
      return true;
    }
    return false;
  }
  const Token& expect_op(char c, const char* what) {
    if (peek().kind != Tok::op || peek().text[0] != c)
      fail(peek(), fmt::format("expected '{}' {}, found {}", c, what, describe(peek())));
    return next();
  }
  static bool is_keyword(const std::string& s) {
    return std::find(std::begin(kKeywords), std::end(kKeywords), s) != std::end(kKeywords);
  }

  // A ',' between the items of a statement's list. A line that ends with ',' continues on the
  // next line (the lexer drops that line break), so what follows must be the next item: not
  // the end of the file, nor a statement keyword on a later line (a stray trailing ',').
  bool accept_list_comma(const std::string& stmt) {
    if (!accept_op(',')) return false;
    check_item_follows(toks_[i_ - 1], stmt);
    return true;
  }
  void check_item_follows(const Token& comma, const std::string& stmt) const {
    const Token& t = peek();
    if (t.kind == Tok::newline || t.kind == Tok::end)
      fail(comma, fmt::format("the '{}' list ends with ',': expected another item after it", stmt));
    if (t.line > comma.line && t.kind == Tok::ident && is_keyword(t.text))
      fail(comma, fmt::format("the '{}' line ends with ',', so it continues on line {}, but that "
                              "line starts a '{}' statement; remove the trailing ','",
                              stmt, t.line, t.text));
  }

  void expect_end_of_statement(const char* stmt) {
    if (peek().kind == Tok::newline) {
      ++i_;
      return;
    }
    if (peek().kind == Tok::end) return;
    fail(peek(), fmt::format("unexpected {} after the '{}' statement", describe(peek()), stmt));
  }

  void statement() {
    const Token& kw = next();
    if (kw.kind == Tok::newline) return;
    if (kw.kind != Tok::ident)
      fail(kw, fmt::format("expected a keyword (model, states, inputs, params, f, g, h, F, domain, "
                           "nominal, option), found {}",
                           describe(kw)));
    const std::string& k = kw.text;
    model_.locations[k] = loc(kw);
    if (k == "model") return model_statement(kw);
    if (k == "states") return declare_list(kw, Declared::state);
    if (k == "inputs") return declare_list(kw, Declared::input);
    if (k == "params") return params_statement(kw);
    if (k == "f" || k == "g" || k == "h" || k == "F") return field_statement(kw);
    if (k == "domain") return domain_statement(kw);
    if (k == "nominal") return nominal_statement(kw);
    std::vector<std::string> kws(std::begin(kKeywords), std::end(kKeywords));
    fail(kw, fmt::format("unknown keyword '{}'{}", k, suggestion(k, kws)));
  }

  void model_statement(const Token& kw) {
    if (!model_.name.empty()) fail(kw, "duplicate 'model' statement");
    const Token& name = next();
    if (name.kind != Tok::ident)
      fail(name, fmt::format("expected the model name after 'model', found {}", describe(name)));
    model_.name = name.text;
    expect_end_of_statement("model");
  }

  // y, t, z1, D, I, Pi, ... are ordinary names here: nothing below reads GiNaC's constants,
  // and the stages name their own symbols around the model's (front/fresh_names.hpp).
  void check_new_name(const Token& t) {
    const std::string& s = t.text;
    if (is_supported_function(s) || s == "pow" || s == "abs")
      fail(t, fmt::format("'{}' is a function name and cannot name a symbol", s));
    if (std::find(std::begin(kKeywords), std::end(kKeywords), s) != std::end(kKeywords) &&
        s != "F" && s != "f" && s != "g" && s != "h")
      fail(t, fmt::format("'{}' is a keyword and cannot name a symbol", s));
    if (s == "f" || s == "g" || s == "h" || s == "F")
      fail(t, fmt::format("'{}' names a vector field and cannot name a symbol", s));
    auto it = names_.find(s);
    if (it != names_.end())
      fail(t, fmt::format("duplicate name '{}': already declared as a {} at {}:{}", s,
                          kind_name(it->second.kind), it->second.loc.line, it->second.loc.col));
  }

  void declare_list(const Token& kw, Declared::Kind kind) {
    auto& list = kind == Declared::state ? model_.states : model_.inputs;
    if (!list.empty()) fail(kw, fmt::format("duplicate '{}' statement", kw.text));
    bool any = false;
    while (peek().kind != Tok::newline && peek().kind != Tok::end) {
      const Token& t = next();
      if (t.kind == Tok::op && t.text == "," && any) {
        check_item_follows(t, kw.text);
        continue;
      }
      if (t.kind != Tok::ident)
        fail(t, fmt::format("expected a name in '{}', found {}", kw.text, describe(t)));
      check_new_name(t);
      GiNaC::symbol s(t.text);
      names_.emplace(t.text, Declared{kind, s, loc(t)});
      list.push_back(s);
      any = true;
    }
    if (!any) fail(peek(), fmt::format("'{}' needs at least one name", kw.text));
    expect_end_of_statement(kw.text.c_str());
  }

  void params_statement(const Token& kw) {
    if (!model_.params.empty()) fail(kw, "duplicate 'params' statement");
    do {
      const Token& t = next();
      if (t.kind != Tok::ident)
        fail(t, fmt::format("expected a parameter name, found {}", describe(t)));
      check_new_name(t);
      Param p{t.text, GiNaC::symbol(t.text), std::nullopt, loc(t)};
      if (accept_op('=')) {
        const Token& at = peek();
        const ex v = expression();
        p.value = numeric_value(v, at, fmt::format("default of parameter '{}'", t.text));
      }
      names_.emplace(t.text, Declared{Declared::param, p.symbol, loc(t)});
      model_.params.push_back(p);
    } while (accept_list_comma("params"));
    expect_end_of_statement("params");
  }

  numeric numeric_value(const ex& v, const Token& at, const std::string& what) {
    for (const auto& s : symbols_in_expr(v)) {
      auto it = names_.find(s);
      if (it != names_.end())
        fail(at, fmt::format("{} must be a number, but it uses the {} '{}'", what,
                             kind_name(it->second.kind), s));
    }
    // numeric::is_real() is false for I^2 = -1, so test the imaginary part instead.
    if (GiNaC::is_a<numeric>(v) && GiNaC::ex_to<numeric>(v).imag().is_zero() &&
        GiNaC::ex_to<numeric>(v).real().is_rational())
      return GiNaC::ex_to<numeric>(v).real();
    check_float_arguments(v, at, what);
    ex e;
    try {
      e = GiNaC::evalf(v);
    } catch (const std::exception& err) {  // e.g. cln::floating_point_underflow_exception
      fail(at, fmt::format("{} cannot be evaluated: {}", what, err.what()));
    }
    if (!GiNaC::is_a<numeric>(e) || !GiNaC::ex_to<numeric>(e).imag().is_zero())
      fail(at, fmt::format("{} must be a real number", what));
    return GiNaC::ex_to<numeric>(e).real();
  }

  // Rounded evaluation goes silently wrong for huge arguments (CLN gives exp(10^400) = 1,
  // sin(10^400) = 0, tanh(10^400) = 0) or throws (exp(-10^400) underflows): refuse them.
  void check_float_arguments(const ex& v, const Token& at, const std::string& what) {
    for (std::size_t k = 0; k < v.nops(); ++k) check_float_arguments(v.op(k), at, what);
    if (!GiNaC::is_a<GiNaC::function>(v)) return;
    const std::string name = GiNaC::ex_to<GiNaC::function>(v).get_name();
    if (name == "log" || name == "atan") return;  // well behaved for any magnitude
    ex a;
    try {
      a = GiNaC::evalf(v.op(0));
    } catch (const std::exception& err) {
      fail(at, fmt::format("{} cannot be evaluated: {}", what, err.what()));
    }
    if (GiNaC::is_a<numeric>(a) && GiNaC::abs(GiNaC::ex_to<numeric>(a)) > numeric(1000000))
      fail(at, fmt::format("{} cannot be evaluated reliably: the argument of {}() exceeds 10^6 in "
                           "magnitude",
                           what, name));
  }

  static std::vector<std::string> symbols_in_expr(const ex& e) {
    std::vector<std::string> out;
    for (const auto& s : symbols_in(e)) out.push_back(s.get_name());
    return out;
  }

  void field_statement(const Token& kw) {
    auto& slot = kw.text == "f" ? f_ : kw.text == "g" ? g_ : kw.text == "h" ? h_ : F_;
    if (slot) fail(kw, fmt::format("duplicate '{}' statement", kw.text));
    expect_op('=', fmt::format("after '{}'", kw.text).c_str());
    ExVec v;
    std::vector<SourceLoc> locs;
    if (accept_op('[')) {
      if (peek().kind == Tok::op && peek().text == "]")
        fail(peek(), fmt::format("'{}' is an empty list", kw.text));
      do {
        locs.push_back(loc(peek()));
        v.push_back(expression());
      } while (accept_op(','));
      expect_op(']', "to close the list");
    } else {
      locs.push_back(loc(peek()));
      v.push_back(expression());
    }
    slot = v;
    for (std::size_t i = 0; i < locs.size(); ++i)
      model_.locations[fmt::format("{}[{}]", kw.text, i)] = locs[i];
    expect_end_of_statement(kw.text.c_str());
  }

  void domain_statement(const Token& kw) {
    if (!model_.domain.empty()) fail(kw, "duplicate 'domain' statement");
    do {
      const Token& t = next();
      if (t.kind != Tok::ident)
        fail(t, fmt::format("expected a name in 'domain', found {}", describe(t)));
      auto it = names_.find(t.text);
      if (it == names_.end())
        fail(t, fmt::format("unknown symbol '{}' in 'domain' (declare it first){}", t.text,
                            suggestion(t.text, declared_names())));
      if (it->second.kind == Declared::param) {
        for (const auto& p : model_.params)
          if (p.name == t.text && p.value)
            fail(t, fmt::format("parameter '{}' has the fixed value {} and needs no domain", t.text,
                                to_string(*p.value)));
      }
      if (model_.domain.count(t.text))
        fail(t, fmt::format("'{}' appears twice in 'domain'", t.text));
      const Token& in = next();
      if (in.kind != Tok::ident || in.text != "in")
        fail(in, fmt::format("expected 'in' after '{}', found {}", t.text, describe(in)));
      expect_op('[', "to open the interval");
      const Token& lo_t = peek();
      const numeric lo = numeric_value(expression(), lo_t, "a domain bound");
      expect_op(',', "between the interval bounds");
      const Token& hi_t = peek();
      const numeric hi = numeric_value(expression(), hi_t, "a domain bound");
      expect_op(']', "to close the interval");
      if (!(lo < hi))
        fail(lo_t,
             fmt::format("empty interval for '{}': lower bound must be below the upper", t.text));
      model_.domain[t.text] = Interval{lo, hi};
    } while (accept_list_comma("domain"));
    expect_end_of_statement("domain");
  }

  // nominal u = 1, v = 2: the input value at which a field given as F is split.
  void nominal_statement(const Token& kw) {
    if (nominal_) fail(kw, "duplicate 'nominal' statement");
    nominal_.emplace();
    nominal_loc_ = loc(kw);
    do {
      const Token& t = next();
      if (t.kind != Tok::ident)
        fail(t, fmt::format("expected an input name in 'nominal', found {}", describe(t)));
      auto it = names_.find(t.text);
      if (it == names_.end() || it->second.kind != Declared::input)
        fail(t, fmt::format("'{}' is not a declared input ('nominal' gives input values; declare "
                            "'inputs' first){}",
                            t.text, suggestion(t.text, input_names())));
      for (const auto& [sym, v, l] : *nominal_)
        if (sym.get_name() == t.text)
          fail(t, fmt::format("'{}' appears twice in 'nominal'", t.text));
      expect_op('=', fmt::format("after '{}' in 'nominal'", t.text).c_str());
      const Token& at = peek();
      const numeric v =
          numeric_value(expression(), at, fmt::format("the nominal value of '{}'", t.text));
      nominal_->push_back({it->second.sym, v, loc(at)});
    } while (accept_list_comma("nominal"));
    expect_end_of_statement("nominal");
  }

  std::vector<std::string> input_names() const {
    std::vector<std::string> out;
    for (const auto& u : model_.inputs) out.push_back(u.get_name());
    return out;
  }

  std::vector<std::string> declared_names() const {
    std::vector<std::string> out;
    for (const auto& [k, v] : names_) out.push_back(k);
    return out;
  }

  // ---- expressions ------------------------------------------------------------------
  struct DepthGuard {
    Parser& p;
    DepthGuard(Parser& pp, const Token& at) : p(pp) {
      if (++p.depth_ > p.lim_.max_nesting)
        p.fail(at, fmt::format("expression nested more than {} levels deep", p.lim_.max_nesting));
    }
    ~DepthGuard() { --p.depth_; }
  };

  template <class Op>
  ex guarded(const Token& at, Op&& op) {
    try {
      return op();
    } catch (const UserError&) {
      throw;
    } catch (const std::exception& e) {
      fail(at, fmt::format("cannot evaluate this expression: {}", e.what()));
    }
  }

  ex expression() {
    DepthGuard guard(*this, peek());
    ex acc = term();
    while (peek().kind == Tok::op && (peek().text == "+" || peek().text == "-")) {
      const Token& op = next();
      const ex rhs = term();
      acc = guarded(op, [&] { return op.text == "+" ? acc + rhs : acc - rhs; });
    }
    return acc;
  }

  ex term() {
    ex acc = unary();
    while (peek().kind == Tok::op && (peek().text == "*" || peek().text == "/")) {
      const Token& op = next();
      const ex rhs = unary();
      if (op.text == "/") {
        if (rhs.is_zero() || (GiNaC::is_a<numeric>(rhs) && GiNaC::ex_to<numeric>(rhs).is_zero()))
          fail(op, "division by zero");
        divisors_.push_back({rhs, loc(op)});
        acc = guarded(op, [&] { return acc / rhs; });
      } else {
        acc = guarded(op, [&] { return acc * rhs; });
      }
    }
    return acc;
  }

  ex unary() {
    DepthGuard guard(*this, peek());
    if (peek().kind == Tok::op && (peek().text == "-" || peek().text == "+")) {
      const bool neg = next().text == "-";
      const ex v = unary();
      return neg ? -v : v;
    }
    return power();
  }

  ex power() {
    const ex base = primary();
    if (peek().kind == Tok::op && peek().text == "^") {
      const Token& op = next();
      const Token& at = peek();
      const ex e = unary();  // right associative, allows x^-1
      if (GiNaC::is_a<numeric>(e)) {
        const numeric& q = GiNaC::ex_to<numeric>(e);
        if (!q.is_rational()) fail(at, "exponent must be a rational number or an expression");
        if (GiNaC::abs(q.numer()) > lim_.max_integer_exponent ||
            q.denom() > lim_.max_integer_exponent)
          fail(at, fmt::format("exponent {} is out of range (limit {})", to_string(e),
                               lim_.max_integer_exponent));
        if (q.is_negative() && base.is_zero()) fail(op, "division by zero (0 to a negative power)");
        // Checked here rather than left to GiNaC, whose exception for 0^0 leaks the power object.
        if (q.is_zero() && base.is_zero()) fail(op, "0^0 is undefined");
        check_folded_power(base, q, at);
        if (q.is_negative()) divisors_.push_back({base, loc(op)});
      } else {
        // Symbolic exponent: only e^(...) style via exp() is supported, keep the model algebraic.
        fail(at, "exponent must be a number; write exp(a*log(b)) for symbolic exponents");
      }
      return guarded(op, [&] { return GiNaC::pow(base, e); });
    }
    return base;
  }

  static long bit_size(const numeric& c) {
    if (!c.is_real()) return bit_size(c.real()) + bit_size(c.imag());
    if (!c.is_rational()) return 64;
    return c.numer().int_length() + c.denom().int_length();
  }
  static long saturating_mul(long a, long b) {
    return (b != 0 && a > (1L << 40) / b) ? (1L << 40) : a * b;
  }

  // GiNaC folds (b^p)^q into b^(p*q) and distributes integer powers over products, so the
  // limits must hold for what comes out, not only for what is written: otherwise
  // (((x1+1)^1000)^1000)^1000 becomes (x1+1)^1000000000 and ((2*x1)^1000)^1000 computes
  // 2^1000000 on the spot.
  void check_folded_power(const ex& base, const numeric& q, const Token& at) {
    const auto check = [&](const ex& b) {
      if (GiNaC::is_a<GiNaC::power>(b) && GiNaC::is_a<numeric>(b.op(1))) {
        const numeric p = GiNaC::ex_to<numeric>(b.op(1)) * q;
        if (p.is_rational() && (GiNaC::abs(p.numer()) > lim_.max_integer_exponent ||
                                p.denom() > lim_.max_integer_exponent))
          fail(at, fmt::format(
                       "exponent out of range: the powers combine to an exponent of {} (limit {})",
                       to_string(p), lim_.max_integer_exponent));
      } else if (GiNaC::is_a<numeric>(b)) {
        if (saturating_mul(bit_size(GiNaC::ex_to<numeric>(b)), GiNaC::abs(q.numer()).to_long()) >
            kMaxExactBits)
          fail(at, fmt::format("number too large: this power has more than {} binary digits",
                               kMaxExactBits));
      } else if (GiNaC::is_a<GiNaC::add>(b)) {
        // GiNaC also pulls the numeric content out of a sum raised to an integer power and
        // raises it on the spot: (2*(1e400*x1 + 5e-400)^999 - 400)^999 hung here.
        const long bits = bit_size(b.integer_content());
        if (saturating_mul(bits, GiNaC::abs(q.numer()).to_long()) > kMaxExactBits)
          fail(at,
               fmt::format("number too large: the numeric factor of this power has more than {} "
                           "binary digits",
                           kMaxExactBits));
      }
    };
    if (GiNaC::is_a<GiNaC::mul>(base)) {
      for (std::size_t k = 0; k < base.nops(); ++k) check(base.op(k));
    } else {
      check(base);
    }
  }

  ex primary() {
    const Token& t = next();
    if (t.kind == Tok::number) return parse_number(t.text, loc(t));
    if (t.kind == Tok::op && t.text == "(") {
      const ex v = expression();
      expect_op(')', "to close the parenthesis");
      return v;
    }
    if (t.kind == Tok::ident) {
      if (peek().kind == Tok::op && peek().text == "(") return call(t);
      auto it = names_.find(t.text);
      if (it != names_.end()) {
        if (it->second.kind == Declared::param) {
          for (const auto& p : model_.params)
            if (p.name == t.text && p.value) return *p.value;
        }
        return it->second.sym;
      }
      if (is_supported_function(t.text))
        fail(t, fmt::format("function '{}' needs an argument in parentheses", t.text));
      fail(t, fmt::format("unknown symbol '{}'{}", t.text, suggestion(t.text, declared_names())));
    }
    fail(t, fmt::format("expected an expression, found {}", describe(t)));
  }

  ex call(const Token& name) {
    if (!is_supported_function(name.text)) {
      std::vector<std::string> fns(std::begin(kFunctions), std::end(kFunctions));
      fail(name, fmt::format(
                     "unsupported function '{}' (supported: sin cos tan exp log sqrt tanh atan){}",
                     name.text, suggestion(name.text, fns)));
    }
    expect_op('(', "");
    const ex a = expression();
    if (peek().kind == Tok::op && peek().text == ",")
      fail(peek(), fmt::format("'{}' takes one argument", name.text));
    expect_op(')', fmt::format("to close the call of '{}'", name.text).c_str());
    const std::string& n = name.text;
    return guarded(name, [&]() -> ex {
      if (n == "sin") return GiNaC::sin(a);
      if (n == "cos") return GiNaC::cos(a);
      if (n == "tan") return GiNaC::tan(a);
      if (n == "exp") return GiNaC::exp(a);
      if (n == "log") {
        if (a.is_zero()) throw std::domain_error("log(0) is undefined");
        return GiNaC::log(a);
      }
      if (n == "sqrt") return GiNaC::sqrt(a);
      if (n == "tanh") return GiNaC::tanh(a);
      return GiNaC::atan(a);
    });
  }

  // ---- whole-model checks --------------------------------------------------------------
  // Later stages and the zero tests below substitute exact rational points and evaluate
  // exactly before rounding, so a short model such as 1/(1e400*x1 + 1e-400)^999 would spend
  // seconds per evaluation in bignum gcds. Bound the size of every exact number that arises.
  struct ExactSize {
    long bits;   // bit size of the exactly computed (numeric) part
    bool exact;  // the whole subexpression evaluates to an exact number
  };
  ExactSize exact_size(const ex& e, const std::map<std::string, long>& point_bits,
                       long& worst) const {
    ExactSize r{0, true};
    if (GiNaC::is_a<numeric>(e)) {
      r.bits = bit_size(GiNaC::ex_to<numeric>(e));
    } else if (GiNaC::is_a<GiNaC::symbol>(e)) {
      auto it = point_bits.find(GiNaC::ex_to<GiNaC::symbol>(e).get_name());
      r.bits = it != point_bits.end() ? it->second : 64;
    } else if (GiNaC::is_a<GiNaC::add>(e) || GiNaC::is_a<GiNaC::mul>(e)) {
      for (std::size_t k = 0; k < e.nops(); ++k) {
        const ExactSize c = exact_size(e.op(k), point_bits, worst);
        r.bits = std::min(r.bits + c.bits, 1L << 40);
        r.exact = r.exact && c.exact;
      }
    } else if (GiNaC::is_a<GiNaC::power>(e) && GiNaC::is_a<numeric>(e.op(1))) {
      const ExactSize b = exact_size(e.op(0), point_bits, worst);
      const numeric& q = GiNaC::ex_to<numeric>(e.op(1));
      const long k = q.is_rational() ? GiNaC::abs(q.numer()).to_long() : 1;
      // An integer power of a product is distributed, so its numeric part is raised too.
      r.exact = b.exact;
      r.bits = (b.exact || GiNaC::is_a<GiNaC::mul>(e.op(0))) ? saturating_mul(b.bits, k) : 0;
    } else {
      // Function calls (and anything else) stay symbolic until rounded: only their
      // arguments are computed exactly.
      for (std::size_t k = 0; k < e.nops(); ++k) exact_size(e.op(k), point_bits, worst);
      r = {0, false};
    }
    worst = std::max(worst, r.bits);
    return r;
  }

  void check_exact_size(const SampleBoxes& boxes) const {
    std::map<std::string, long> point_bits;
    for (const auto& [name, box] : boxes.by_name)
      point_bits[name] = 2 * (bit_size(box.lo) + bit_size(box.hi)) + 48;
    const auto check = [&](const ex& e, const SourceLoc& l) {
      long worst = 0;
      exact_size(e, point_bits, worst);
      if (worst > kMaxEvaluationBits)
        throw UserError(l,
                        fmt::format("expression too large: evaluating it exactly at a point needs "
                                    "numbers of about {} binary digits (limit {})",
                                    worst, kMaxEvaluationBits));
    };
    const std::pair<const char*, const ExVec*> fields[] = {
        {F_ ? "F" : "f", &model_.f}, {F_ ? "F" : "g", &model_.g}, {"h", &model_.h}};
    for (const auto& [key, vec] : fields)
      for (std::size_t i = 0; i < vec->size(); ++i) {
        const SourceLoc l = where(fmt::format("{}[{}]", key, i));
        check((*vec)[i], l);
        // sqrt(-1) and log(-2) evaluate to I and log(2) + I*Pi: the model must stay real.
        if (has_nonreal_number((*vec)[i]))
          throw UserError(
              l, fmt::format("{}[{}] is not real: {} (the imaginary unit comes from sqrt or "
                             "log of a negative number)",
                             key, i + 1, to_string((*vec)[i])));
      }
    for (const auto& [d, l] : divisors_) check(d, l);
  }

  // A product vanishes only where a factor does, b^k (k > 0) only where b does, and b^k
  // (k <= 0) nowhere, so zero-test the factors: the whole divisor (5e400*x1 + 1.1e-40)^-999
  // is tiny enough to pass for zero numerically, and proving it then took minutes.
  static void zero_candidates(const ex& d, std::vector<ex>& out) {
    if (GiNaC::is_a<GiNaC::mul>(d)) {
      for (std::size_t k = 0; k < d.nops(); ++k) zero_candidates(d.op(k), out);
    } else if (GiNaC::is_a<GiNaC::power>(d) && GiNaC::is_a<numeric>(d.op(1))) {
      if (GiNaC::ex_to<numeric>(d.op(1)).is_positive()) zero_candidates(d.op(0), out);
    } else if (GiNaC::is_a<GiNaC::function>(d) &&
               (GiNaC::ex_to<GiNaC::function>(d).get_name() == "exp")) {
      // never zero
    } else if (GiNaC::is_a<GiNaC::function>(d) &&
               (GiNaC::ex_to<GiNaC::function>(d).get_name() == "atan" ||
                GiNaC::ex_to<GiNaC::function>(d).get_name() == "tanh")) {
      zero_candidates(d.op(0), out);  // zero exactly where the argument is
    } else if (!GiNaC::is_a<numeric>(d) || d.is_zero()) {
      out.push_back(d);
    }
  }

  void check_divisors(const SampleBoxes& boxes) const {
    for (const auto& [d, l] : divisors_) {
      std::vector<ex> factors;
      zero_candidates(d, factors);
      for (const auto& f : factors) {
        // With no real sample value, zero_test falls back on a symbolic proof, which took
        // minutes on nested trigonometric divisors such as sin(...)^(201/10) found by fuzzing.
        if (!real_somewhere(f, boxes))
          throw UserError(l, fmt::format("division by an expression that is not real anywhere in "
                                         "the domain box: {} (declare a 'domain' where it is real)",
                                         to_string(f)));
        if (zero_test(f, boxes) != ZeroVerdict::nonzero)
          throw UserError(l, fmt::format("division by an expression that is identically zero: {}",
                                         to_string(f)));
      }
    }
  }

  // Rounded evaluation of sin, cos, tan, exp and tanh goes wrong once the argument is huge:
  // sin(-5^1000 + x2) evaluated to 0 at every point, and the zero test then spent seconds
  // "proving" a divisor zero. Bound the arguments near the corners of the domain box.
  void check_function_arguments(const SampleBoxes& boxes) const {
    const std::vector<GiNaC::exmap> points = sample_points(model_.all_symbols(), boxes, 2, 1);
    const std::pair<const char*, const ExVec*> fields[] = {
        {F_ ? "F" : "f", &model_.f}, {F_ ? "F" : "g", &model_.g}, {"h", &model_.h}};
    const DigitsGuard digits(40);
    for (const auto& pt : points) {
      GiNaC::exmap fpt;
      for (const auto& [sym, value] : pt) fpt[sym] = GiNaC::evalf(value);
      for (const auto& [key, vec] : fields)
        for (std::size_t i = 0; i < vec->size(); ++i)
          check_function_arguments((*vec)[i], fpt, where(fmt::format("{}[{}]", key, i)));
    }
  }

  static void check_function_arguments(const ex& e, const GiNaC::exmap& pt, const SourceLoc& l) {
    for (std::size_t k = 0; k < e.nops(); ++k) check_function_arguments(e.op(k), pt, l);
    if (!GiNaC::is_a<GiNaC::function>(e)) return;
    const std::string name = GiNaC::ex_to<GiNaC::function>(e).get_name();
    if (name == "log" || name == "atan") return;  // well behaved for any magnitude
    ex a;
    try {
      a = GiNaC::evalf(e.op(0).subs(pt));
    } catch (const std::exception&) {
      return;  // undefined at this point: not a magnitude problem
    }
    if (GiNaC::is_a<numeric>(a) && GiNaC::abs(GiNaC::ex_to<numeric>(a)) > numeric(1000000))
      throw UserError(
          l, fmt::format("the argument of {}() exceeds 10^6 in magnitude in the domain box, "
                         "where {}() cannot be evaluated reliably",
                         name, name));
  }

  static bool real_somewhere(const ex& e, const SampleBoxes& boxes) {
    const ZeroTestOptions opt;
    for (const auto& pt : sample_points(symbols_in(e), boxes, opt.points, opt.seed)) {
      numeric v;
      if (evaluate_real(e, pt, opt.digits, v)) return true;
    }
    return false;
  }

  template <class OnPole>
  static void check_poles_at_zero(const ex& e, const GiNaC::exmap& zero, const OnPole& on_pole) {
    for (std::size_t k = 0; k < e.nops(); ++k) check_poles_at_zero(e.op(k), zero, on_pole);
    if (GiNaC::is_a<GiNaC::power>(e) && GiNaC::is_a<numeric>(e.op(1)) &&
        !GiNaC::ex_to<numeric>(e.op(1)).is_positive() && e.op(0).subs(zero).is_zero())
      on_pole(e.op(0));
  }

  static bool has_nonreal_number(const ex& e) {
    if (GiNaC::is_a<numeric>(e))
      return !GiNaC::ex_to<numeric>(e).imag().is_zero();  // I^2 is not is_real()
    for (std::size_t k = 0; k < e.nops(); ++k)
      if (has_nonreal_number(e.op(k))) return true;
    return false;
  }

  SourceLoc where(const std::string& key) const {
    auto it = model_.locations.find(key);
    return it != model_.locations.end() ? it->second : SourceLoc{file_, 1, 1};
  }

  // e at an input point, or nullopt with why: substituting can throw (a pole such as 1/u,
  // log(u) at 0), and that is the user's model, not a bug. GiNaC leaks the half-built term
  // when a pole makes subs() throw (x2/u*x2 with u = 0), so look for vanishing denominators
  // first, innermost first.
  static std::optional<ex> value_at(const ex& e, const GiNaC::exmap& at, std::string& why) {
    try {
      std::optional<std::string> pole;
      check_poles_at_zero(e, at, [&](const ex& base) {
        if (!pole) pole = fmt::format("it divides by {}, which vanishes there", to_string(base));
      });
      if (pole) {
        why = *pole;
        return std::nullopt;
      }
      return e.subs(at);
    } catch (const std::exception& err) {  // e.g. log(u)
      why = err.what();
      return std::nullopt;
    }
  }

  std::string input_point_text(const std::vector<numeric>& v) const {
    std::vector<std::string> parts;
    for (std::size_t k = 0; k < model_.inputs.size(); ++k)
      parts.push_back(fmt::format("{} = {}", model_.inputs[k].get_name(), to_string(v[k])));
    return fmt::format("{}", fmt::join(parts, ", "));
  }

  GiNaC::exmap input_point(const std::vector<numeric>& v) const {
    GiNaC::exmap at;
    for (std::size_t k = 0; k < model_.inputs.size(); ++k) at[model_.inputs[k]] = v[k];
    return at;
  }

  GiNaC::exmap input_zero() const {
    GiNaC::exmap u_zero;
    for (const auto& u : model_.inputs) u_zero[u] = 0;
    return u_zero;
  }

  void check_len(const char* key, const ExVec& v) const {
    const std::size_t n = model_.states.size();
    if (v.size() != n)
      throw UserError(where(key), fmt::format("'{}' has {} component{}, but there {} {} state{}",
                                              key, v.size(), v.size() == 1 ? "" : "s",
                                              n == 1 ? "is" : "are", n, n == 1 ? "" : "s"));
  }

  // The statements every model needs, and F or f (+ g) but not both.
  void check_required() const {
    const Token& eof = toks_.back();
    const SourceLoc end{file_, eof.line, eof.col};
    if (model_.name.empty())
      throw UserError(SourceLoc{file_, 1, 1}, "missing 'model NAME' statement");
    if (model_.states.empty()) throw UserError(end, "missing 'states' statement");
    if (F_ && (f_ || g_))
      throw UserError(where("F"), "give either 'F = [...]' or 'f = [...]' (and 'g'), not both");
    if (!f_ && !F_) throw UserError(end, "missing 'f = [...]' (the drift vector field)");
    if (!h_) throw UserError(end, "missing 'h = [...]' (the output map)");
  }

  // The 'nominal' line's input values, each inside its domain.
  std::vector<numeric> nominal_from_line() {
    std::vector<numeric> u0(model_.inputs.size(), numeric(0));
    for (const auto& nv : *nominal_) {
      std::size_t k = 0;
      while (!(model_.inputs[k] == nv.input)) ++k;
      u0[k] = nv.value;
      const auto box = model_.domain.find(nv.input.get_name());
      if (box != model_.domain.end() && (nv.value < box->second.lo || nv.value > box->second.hi))
        throw UserError(nv.loc, fmt::format("the nominal value {} of '{}' is outside its "
                                            "domain [{}, {}]",
                                            to_string(nv.value), nv.input.get_name(),
                                            to_string(box->second.lo), to_string(box->second.hi)));
    }
    model_.nominal = u0;
    model_.nominal_note =
        fmt::format("F split at the nominal input {} (the 'nominal' line)", input_point_text(u0));
    return u0;
  }

  // 0, else (F undefined at 0) the middle of the input box, stated in nominal_note; an error
  // when F is undefined there too.
  std::vector<numeric> nominal_fallback() {
    const std::size_t n = model_.states.size();
    const GiNaC::exmap u_zero = input_zero();
    for (std::size_t i = 0; i < n; ++i) {
      std::string why;
      if (value_at((*F_)[i], u_zero, why)) continue;
      std::vector<numeric> mid;
      for (const auto& u : model_.inputs) {
        const Interval b = model_.box(u);
        mid.push_back((b.lo + b.hi) / 2);
      }
      bool defined = true;
      std::string why_mid;
      for (std::size_t j = 0; j < n && defined; ++j)
        defined = value_at((*F_)[j], input_point(mid), why_mid).has_value();
      if (!defined)
        throw UserError(
            where(fmt::format("F[{}]", i)),
            fmt::format("F[{}] is undefined at u = 0 ({}) and F at the middle of the input "
                        "box ({}: {}); add a line 'nominal {} = VALUE' with an input value "
                        "where F is defined, to split F there",
                        i + 1, why, input_point_text(mid), why_mid,
                        model_.inputs.empty() ? "u" : model_.inputs[0].get_name()));
      model_.nominal = mid;
      model_.nominal_note = fmt::format(
          "F split at the nominal input {} (the middle of the input box), because F[{}] is "
          "undefined at u = 0 ({}); a 'nominal' line sets another value",
          input_point_text(mid), i + 1, why);
      return mid;
    }
    return std::vector<numeric>(model_.inputs.size(), numeric(0));
  }

  // F = [...]: split at the nominal input u0 into f = F(x, u0) and g = F - f.
  void split_F() {
    check_len("F", *F_);
    // The nominal input u0: the 'nominal' line, else 0, else (F undefined at 0) the middle of
    // the input box, stated in nominal_note; never a silent guess.
    const std::vector<numeric> u0 = nominal_ ? nominal_from_line() : nominal_fallback();
    const GiNaC::exmap at = input_point(u0);
    for (std::size_t i = 0; i < model_.states.size(); ++i) {
      const ex& c = (*F_)[i];
      std::string why;
      const auto c0 = value_at(c, at, why);
      if (!c0)
        throw UserError(where(fmt::format("F[{}]", i)),
                        fmt::format("F[{}] is undefined at the nominal input {} ({})", i + 1,
                                    input_point_text(u0), why));
      model_.f.push_back(*c0);
      model_.g.push_back(c - *c0);
    }
  }

  // f = [...] (free of the inputs) and g = [...] (default 0).
  void take_f_g() {
    const std::size_t n = model_.states.size();
    check_len("f", *f_);
    model_.f = *f_;
    for (std::size_t i = 0; i < n; ++i) {
      const SourceLoc l = where(fmt::format("f[{}]", i));
      for (const auto& u : model_.inputs)
        if (model_.f[i].has(u))
          throw UserError(l, fmt::format("f[{}] depends on the input '{}'; put input terms in 'g' "
                                         "(or give the whole field as 'F')",
                                         i + 1, u.get_name()));
    }
    if (g_) {
      check_len("g", *g_);
      model_.g = *g_;
    } else {
      model_.g.assign(n, ex(0));
    }
  }

  // Outputs may depend on the inputs (direct feedthrough, y = h(x,u)); the drift analysis
  // reads them at the nominal input, so they must be defined there.
  void check_outputs_at_nominal() const {
    std::vector<numeric> u0 = model_.nominal;
    u0.resize(model_.inputs.size(), numeric(0));
    for (std::size_t i = 0; i < model_.h.size(); ++i) {
      if (!depends_on(model_.h[i], model_.inputs)) continue;
      std::string why;
      if (!value_at(model_.h[i], input_point(u0), why))
        throw UserError(where(fmt::format("h[{}]", i)),
                        fmt::format("h[{}] is undefined at the input {} ({}); the drift "
                                    "analysis reads the outputs there",
                                    i + 1, input_point_text(u0), why));
    }
  }

  // A given g must be defined and zero at u = 0.
  void check_g_zero_at_zero(const SampleBoxes& boxes) {
    const GiNaC::exmap u_zero = input_zero();
    for (std::size_t i = 0; i < model_.states.size(); ++i) {
      std::string why;
      const auto v = value_at(model_.g[i], u_zero, why);
      if (!v)
        throw UserError(where(fmt::format("{}[{}]", "g", i)),
                        fmt::format("{}[{}] is undefined at u = 0 ({}); the input part g(x,u) must "
                                    "be defined and zero at u = 0",
                                    "g", i + 1, why));
      const ex g0 = *v;
      if (!real_somewhere(g0, boxes) || zero_test(g0, boxes) == ZeroVerdict::nonzero)
        throw UserError(
            where(fmt::format("g[{}]", i)),
            fmt::format("g[{}] is not zero at u = 0 (it is {} there); move that part to 'f'", i + 1,
                        to_string(g0)));
    }
  }

  Model finish() {
    check_required();
    if (nominal_ && !F_)
      throw UserError(nominal_loc_,
                      "'nominal' sets where a field given as 'F = [...]' is split (f = F(x,u0), "
                      "g = F - f); with 'f' and 'g' the split is already explicit");
    if (F_)
      split_F();
    else
      take_f_g();
    model_.h = *h_;
    check_outputs_at_nominal();
    const SampleBoxes boxes = model_.sample_boxes();
    check_exact_size(boxes);
    check_function_arguments(boxes);
    if (g_) check_g_zero_at_zero(boxes);
    check_divisors(boxes);
    return model_;
  }
};

}  // namespace

bool is_supported_function(const std::string& name) {
  return std::find(std::begin(kFunctions), std::end(kFunctions), name) != std::end(kFunctions);
}

Model parse_model(std::string_view text, const std::string& filename, const ParseLimits& limits) {
  std::string src(text);
  std::vector<ModelOption> options = take_option_lines(src, filename);
  Lexer lexer(src, filename, limits);
  Parser parser(lexer.run(), filename, limits);
  Model m = parser.run();
  m.options = std::move(options);
  return m;
}

ExVec parse_expression_list(std::string_view text, const std::string& what,
                            const std::vector<GiNaC::symbol>& symbols, const ParseLimits& limits) {
  Lexer lexer(text, what, limits);
  Parser parser(lexer.run(), what, limits);
  return parser.standalone_list(symbols);
}

Model load_model(const std::string& path, const ParseLimits& limits) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw UserError(SourceLoc{path, 0, 0}, "cannot open the model file");
  std::stringstream ss;
  ss << in.rdbuf();
  return parse_model(ss.str(), path, limits);
}

GiNaC::numeric parse_real_number(const std::string& text, const std::string& what) {
  ExVec v;
  try {
    v = parse_expression_list(text, what, {});
  } catch (const UserError&) {
    v.clear();
  }
  if (v.size() != 1 || !GiNaC::is_a<GiNaC::numeric>(v[0]) ||
      !GiNaC::ex_to<GiNaC::numeric>(v[0]).is_real())
    throw UserError(SourceLoc{}, fmt::format("{}: '{}' is not a real number", what, text));
  return GiNaC::ex_to<GiNaC::numeric>(v[0]);
}

}  // namespace obsynth
