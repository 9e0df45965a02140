// Tests for the .sym front end (design.md §2 and §5 "Front end"): one test per diagnostic,
// each checking the exact line and column and the key words of the message, plus the
// deliberate behaviours (exact decimals, F split, domain boxes, nesting cap, names, line breaks)
// and a check that every shipped model parses.

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <initializer_list>
#include <string>
#include <string_view>
#include <vector>

#include "foundation/diagnostics.hpp"
#include "front/fresh_names.hpp"
#include "front/model.hpp"
#include "front/parse.hpp"
#include "symbolic/expr_print.hpp"

#ifndef OBSYNTH_SOURCE_DIR
#error "compile with -DOBSYNTH_SOURCE_DIR=\"<repository root>\""
#endif

namespace {

using GiNaC::ex;
using GiNaC::numeric;
using obsynth::Model;
using obsynth::parse_model;
using obsynth::UserError;

const char* const kFile = "test.sym";

// Parses `text`, which must fail; checks the first diagnostic's position and that its message
// contains every one of `words`.
testing::AssertionResult FailsAt(std::string_view text, int line, int col,
                                 std::initializer_list<std::string_view> words) {
  try {
    const Model m = parse_model(text, kFile);
    return testing::AssertionFailure() << "parsed without a diagnostic (model '" << m.name << "')";
  } catch (const UserError& e) {
    if (e.diagnostics().empty())
      return testing::AssertionFailure() << "UserError without diagnostics";
    const obsynth::Diagnostic& d = e.diagnostics().front();
    const std::string shown = obsynth::format_diagnostic(d);
    if (d.severity != obsynth::Severity::error)
      return testing::AssertionFailure() << "not an error: " << shown;
    if (d.loc.file != kFile) return testing::AssertionFailure() << "wrong file in: " << shown;
    if (d.loc.line != line || d.loc.col != col)
      return testing::AssertionFailure() << "expected " << line << ":" << col << ", got: " << shown;
    for (std::string_view w : words)
      if (d.message.find(w) == std::string::npos)
        return testing::AssertionFailure() << "message lacks \"" << w << "\": " << shown;
    return testing::AssertionSuccess() << shown;
  }
}

Model Parse(std::string_view text) {
  try {
    return parse_model(text, kFile);
  } catch (const UserError& e) {
    ADD_FAILURE() << "unexpected diagnostic: " << e.what();
    throw;
  }
}

GiNaC::symbol Sym(const Model& m, const std::string& name) {
  for (const auto& s : m.all_symbols())
    if (s.get_name() == name) return s;
  ADD_FAILURE() << "no symbol '" << name << "' in the model";
  return GiNaC::symbol(name);
}

bool Same(const ex& a, const ex& b) {
  return (a - b).expand().is_zero();
}

// A valid two-state header: "model m", "states x1 x2" on lines 1-2.
const std::string kHead = "model m\nstates x1 x2\n";

// ---- symbols -------------------------------------------------------------------------------

TEST(ParseDiagnostics, UnknownSymbolSuggestsDeclaredName) {
  EXPECT_TRUE(
      FailsAt("model m\nstates angle velocity\nf = [velocity, -sin(angle) - velocty]\nh = angle\n",
              3, 30, {"unknown symbol 'velocty'", "did you mean 'velocity'?"}));
  EXPECT_TRUE(
      FailsAt(kHead + "f = [x2, -x3]\nh = [x1]\n", 3, 11, {"unknown symbol 'x3'", "did you mean"}));
}

TEST(ParseDiagnostics, UnknownSymbolWithoutCloseMatchHasNoSuggestion) {
  try {
    parse_model(kHead + "f = [x2, -temperature]\nh = [x1]\n", kFile);
    FAIL() << "parsed";
  } catch (const UserError& e) {
    const auto& d = e.diagnostics().front();
    EXPECT_EQ(d.loc.line, 3);
    EXPECT_EQ(d.loc.col, 11);
    EXPECT_NE(d.message.find("unknown symbol 'temperature'"), std::string::npos) << d.message;
    EXPECT_EQ(d.message.find("did you mean"), std::string::npos) << d.message;
  }
}

TEST(ParseDiagnostics, MisspelledKeywordSuggestsStates) {
  EXPECT_TRUE(FailsAt("model m\nstats x1 x2\n", 2, 1,
                      {"unknown keyword 'stats'", "did you mean 'states'?"}));
  EXPECT_TRUE(
      FailsAt("model m\n  input u\n", 2, 3, {"unknown keyword 'input'", "did you mean 'inputs'?"}));
}

TEST(ParseDiagnostics, DuplicateStateName) {
  EXPECT_TRUE(FailsAt("model m\nstates x1 x1\n", 2, 11, {"duplicate name 'x1'", "state", "2:8"}));
}

TEST(ParseDiagnostics, StateAndInputWithTheSameName) {
  EXPECT_TRUE(FailsAt(kHead + "inputs x2\n", 3, 8, {"duplicate name 'x2'", "state", "2:11"}));
}

TEST(ParseDiagnostics, StateUsedAsParameter) {
  EXPECT_TRUE(FailsAt(kHead + "params x1 = 2\nf = [x2, -x1]\nh = [x1]\n", 3, 8,
                      {"duplicate name 'x1'", "already declared as a state"}));
}

TEST(ParseDiagnostics, NameClashingWithFunction) {
  EXPECT_TRUE(FailsAt("model m\nstates sin\n", 2, 8, {"'sin'", "function name"}));
  EXPECT_TRUE(FailsAt(kHead + "inputs u, exp\n", 3, 11, {"'exp'", "function name"}));
  EXPECT_TRUE(FailsAt(kHead + "params atan = 1\n", 3, 8, {"'atan'", "function name"}));
}

TEST(ParseDiagnostics, KeywordsAndFieldNamesCannotNameSymbols) {
  EXPECT_TRUE(FailsAt("model m\nstates x1 domain\n", 2, 11, {"'domain'", "keyword"}));
  EXPECT_TRUE(FailsAt("model m\nstates x1 h\n", 2, 11, {"'h'", "vector field"}));
}

// The names engineers write (a dilution rate D, a current I, a state y) are theirs: the parser
// keeps them as the symbols' names, and nothing reads them as GiNaC constants.
TEST(ParseNames, NamesTheStagesUseThemselvesAreAccepted) {
  const Model m = Parse(
      "model bio\nstates S y z1 t\ninputs I\nparams D, Pi = 3, Euler, Catalan, y1 = 2\n"
      "f = [-D*S - S*y, S*y - D*y, -z1 + t, Euler*Catalan - t]\ng = [I, 0, 0, Pi*I]\n"
      "h = [y + y1*z1]\ndomain D in [0.1, 0.5], I in [0, 2]\n");
  ASSERT_EQ(m.n(), 4u);
  EXPECT_EQ(m.states[1].get_name(), "y");
  EXPECT_EQ(m.states[2].get_name(), "z1");
  EXPECT_EQ(m.states[3].get_name(), "t");
  EXPECT_EQ(m.inputs[0].get_name(), "I");
  ASSERT_EQ(m.params.size(), 5u);
  EXPECT_EQ(m.params[0].name, "D");
  EXPECT_EQ(m.params[0].symbol.get_name(), "D");
  const ex S = Sym(m, "S"), y = Sym(m, "y"), z1 = Sym(m, "z1"), I = Sym(m, "I");
  const ex D = Sym(m, "D"), E = Sym(m, "Euler"), C = Sym(m, "Catalan");
  // Hand-written expectations: Pi = 3 and y1 = 2 substituted, the rest symbols.
  EXPECT_TRUE(Same(m.f[0], -D * S - S * y));
  EXPECT_TRUE(Same(m.f[3], E * C - Sym(m, "t")));
  EXPECT_TRUE(Same(m.g[3], 3 * I));
  EXPECT_TRUE(Same(m.h[0], y + 2 * z1));
  EXPECT_FALSE(m.f[3].has(GiNaC::Euler));
  EXPECT_FALSE(m.g[3].has(GiNaC::I));
  EXPECT_EQ(m.domain.at("D").hi, numeric(1, 2));
  EXPECT_EQ(m.domain.at("I").hi, numeric(2));
}

// The stages' own symbols give way to the model's names: a state y pushes the measured output
// to y_, a state z2 the canonical coordinates to z_1, z_2 (never a mixture).
TEST(ParseNames, StageSymbolsAvoidTheModelsNames) {
  const Model m = Parse(
      "model m\nstates y z2\ninputs y_\nparams c1 = 1\n"
      "f = [z2, -y]\ng = [y_, 0]\nh = y\n");
  EXPECT_EQ(obsynth::fresh_symbol(m, "y").get_name(), "y__");
  EXPECT_EQ(obsynth::fresh_symbol(m, "w").get_name(), "w");
  const auto z = obsynth::fresh_symbols(m, "z", 2);
  ASSERT_EQ(z.size(), 2u);
  EXPECT_EQ(z[0].get_name(), "z_1");
  EXPECT_EQ(z[1].get_name(), "z_2");
  EXPECT_EQ(obsynth::fresh_symbols(m, "z", 1)[0].get_name(), "z1");   // z1 is free
  EXPECT_EQ(obsynth::fresh_symbols(m, "c", 2)[1].get_name(), "c_2");  // fixed parameters too
  EXPECT_EQ(obsynth::fresh_symbols(m, "y_d", 2, 0)[1].get_name(), "y_d1");
  const auto y = obsynth::measurement_symbols(m);
  ASSERT_EQ(y.size(), 1u);
  EXPECT_EQ(y[0].get_name(), "y__");
  const Model two = Parse(kHead + "f = [x2, -x1]\nh = [x1, x2]\n");
  const auto y2 = obsynth::measurement_symbols(two);
  ASSERT_EQ(y2.size(), 2u);
  EXPECT_EQ(y2[0].get_name(), "y1");
  EXPECT_EQ(y2[1].get_name(), "y2");
}

TEST(ParseDiagnostics, ConstantNamesIAndPiAreNotConstantsInExpressions) {
  // Undeclared, they are unknown symbols, never the built-in constants.
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, Pi*x1]\nh = [x1]\n", 3, 10, {"unknown symbol 'Pi'"}));
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, x1 + I]\nh = [x1]\n", 3, 15, {"unknown symbol 'I'"}));
  // Case matters: 'pi' and 'i' are ordinary names.
  const Model m = Parse("model m\nstates pi i\nf = [i, -pi]\nh = pi\n");
  ASSERT_EQ(m.n(), 2u);
  EXPECT_TRUE(Same(m.f[1], -Sym(m, "pi")));
  EXPECT_FALSE(GiNaC::is_a<GiNaC::constant>(m.f[1].op(0)));
}

// ---- vector fields -------------------------------------------------------------------------

TEST(ParseDiagnostics, WrongLengthOfF) {
  EXPECT_TRUE(
      FailsAt(kHead + "f = [x2, x1, 0]\nh = [x1]\n", 3, 1, {"'f' has 3 components", "2 states"}));
}

TEST(ParseDiagnostics, WrongLengthOfG) {
  EXPECT_TRUE(FailsAt(kHead + "inputs u\nf = [x2, x1]\ng = [u]\nh = [x1]\n", 5, 1,
                      {"'g' has 1 component", "2 states"}));
  // A scalar g is a one-component list, so it has the wrong length for two states.
  EXPECT_TRUE(
      FailsAt(kHead + "inputs u\nf = [x2, x1]\ng = u\nh = [x1]\n", 5, 1, {"'g' has 1 component"}));
}

TEST(ParseDiagnostics, WrongLengthOfF_CapitalF) {
  EXPECT_TRUE(
      FailsAt(kHead + "inputs u\nF = [x2]\nh = [x1]\n", 4, 1, {"'F' has 1 component", "2 states"}));
}

// Issue 8: outputs may depend on the inputs (direct feedthrough, e.g. an accelerometer reading
// a force); they used to be rejected with "outputs must be h(x)".
TEST(ParseDiagnostics, OutputMayDependOnTheInput) {
  const Model m = Parse(kHead + "inputs u\nf = [x2, x1]\nh = [x1, x1*u]\n");
  EXPECT_TRUE(m.feedthrough());
  EXPECT_TRUE(Same(m.h[1], Sym(m, "x1") * m.inputs[0]));
}

TEST(ParseDiagnostics, EmptyListIsRejected) {
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, x1]\nh = [ ]\n", 4, 7, {"'h' is an empty list"}));
}

TEST(ParseDiagnostics, DriftMustNotDependOnTheInput) {
  EXPECT_TRUE(FailsAt(kHead + "inputs u\nf = [x2, -x1 + u]\nh = [x1]\n", 4, 10,
                      {"f[2]", "input 'u'", "'g'"}));
}

TEST(ParseDiagnostics, MissingH) {
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, x1]\n", 4, 1, {"missing 'h"}));
}

TEST(ParseDiagnostics, MissingFStatesAndModel) {
  EXPECT_TRUE(FailsAt(kHead + "h = [x1]\n", 4, 1, {"missing 'f"}));
  EXPECT_TRUE(FailsAt("model m\nf = [1]\n", 3, 1, {"missing 'states'"}));
  EXPECT_TRUE(FailsAt("states x1\nf = [x1]\nh = x1\n", 1, 1, {"missing 'model"}));
}

TEST(ParseDiagnostics, DuplicateStatement) {
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, x1]\nf = [x2, x1]\n", 4, 1, {"duplicate 'f'"}));
  EXPECT_TRUE(FailsAt(kHead + "states x3\n", 3, 1, {"duplicate 'states'"}));
}

TEST(ParseDiagnostics, GNotZeroAtZeroInput) {
  EXPECT_TRUE(FailsAt(kHead + "inputs u\nf = [x2, x1]\ng = [0, 1 + u]\nh = [x1]\n", 5, 9,
                      {"g[2] is not zero at u = 0", "'f'"}));
  // Zero at u = 0 only through an identity still passes.
  const Model m =
      Parse(kHead + "inputs u\nf = [x2, x1]\ng = [cos(u)^2 + sin(u)^2 - 1, u*x1]\nh = [x1]\n");
  EXPECT_EQ(m.g.size(), 2u);
}

TEST(ParseDiagnostics, GUndefinedAtZeroInput) {
  // Found by fuzz/fuzz_parse.cpp: substituting u = 0 into 1/u threw GiNaC's pole_error.
  EXPECT_TRUE(FailsAt(kHead + "inputs u\nf = [x2, x1]\ng = [0, 0.3/u]\nh = [x1]\n", 5, 9,
                      {"g[2] is undefined at u = 0"}));
  EXPECT_TRUE(FailsAt(kHead + "inputs u\nF = [x2, x1 + 1/u]\nh = [x1]\n", 4, 10,
                      {"F[2] is undefined at u = 0"}));
  EXPECT_TRUE(FailsAt(kHead + "inputs u, v\nF = [x2 / u*x2, -(1+x1) + u*v]\nh = [x1, x2]\n", 4, 6,
                      {"F[1] is undefined at u = 0"}));
  EXPECT_TRUE(FailsAt(kHead + "inputs u\nf = [x2, x1]\ng = [0, log(u)]\nh = [x1]\n", 5, 9,
                      {"g[2]", "u = 0"}));
  EXPECT_TRUE(FailsAt(kHead + "inputs u\nf = [x2, x1]\ng = [0, 1/log(u)]\nh = [x1]\n", 5, 9,
                      {"g[2]", "u = 0"}));
  EXPECT_TRUE(FailsAt(kHead + "inputs u, v\nF = [x1*x1, -x1 + (1+x1)*u + 5/v^2 + u*v]\nh = [x2]\n",
                      4, 13, {"F[2] is undefined at u = 0", "divides by v"}));
}

TEST(ParseDiagnostics, BothFAndCapitalF) {
  EXPECT_TRUE(FailsAt(kHead + "inputs u\nF = [x2, -x1]\nf = [x2, x1]\nh = [x1]\n", 4, 1,
                      {"either 'F", "not both"}));
}

// ---- brackets, empty input, lexical errors ---------------------------------------------------

TEST(ParseDiagnostics, MissingClosingBracket) {
  // Reported at the bracket that is never closed.
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, x1\nh = [x1]\n", 3, 5, {"unbalanced '['", "never closed"}));
}

TEST(ParseDiagnostics, ExtraClosingParenthesis) {
  EXPECT_TRUE(
      FailsAt(kHead + "f = [x2, x1]\nh = x1)\n", 4, 7, {"unbalanced ')'", "no matching '('"}));
  EXPECT_TRUE(
      FailsAt(kHead + "f = [x2, (x1))]\nh = x1\n", 3, 14, {"')' closes the '[' opened at 3:5"}));
}

TEST(ParseDiagnostics, MismatchedBrackets) {
  EXPECT_TRUE(
      FailsAt(kHead + "f = [x2, x1)\nh = [x1]\n", 3, 12, {"')' closes the '[' opened at 3:5"}));
  EXPECT_TRUE(
      FailsAt(kHead + "f = [x2, (x1]\nh = [x1]\n", 3, 13, {"']' closes the '(' opened at 3:10"}));
}

TEST(ParseDiagnostics, EmptyFile) {
  EXPECT_TRUE(FailsAt("", 1, 1, {"empty model"}));
  EXPECT_TRUE(FailsAt("\n\n  \t\n", 1, 1, {"empty model"}));
}

TEST(ParseDiagnostics, FileWithOnlyComments) {
  EXPECT_TRUE(FailsAt("# a model\n   # to be written\n\n#", 1, 1, {"empty model"}));
}

TEST(ParseDiagnostics, UnexpectedCharacters) {
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, x1 % 2]\nh = x1\n", 3, 13, {"unexpected character '%'"}));
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, x1]\nh = x1\x01\n", 4, 7, {"unexpected byte 0x01"}));
}

TEST(ParseDiagnostics, MalformedNumbers) {
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, 1.2.3*x1]\nh = x1\n", 3, 10, {"malformed number '1.2.3'"}));
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, 1e999*x1]\nh = x1\n", 3, 10, {"exponent", "out of range"}));
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, " + std::string(500, '7') + "]\nh = x1\n", 3, 10,
                      {"number literal longer than"}));
}

TEST(ParseDiagnostics, ExpressionSyntax) {
  EXPECT_TRUE(
      FailsAt(kHead + "f = [x2, x1 *]\nh = x1\n", 3, 14, {"expected an expression", "']'"}));
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, x1]\nh x1\n", 4, 3, {"expected '='", "after 'h'"}));
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, x1] x2\nh = x1\n", 3, 14, {"unexpected 'x2'", "'f'"}));
  EXPECT_TRUE(
      FailsAt(kHead + "f = [x2, sin x1]\nh = x1\n", 3, 10, {"'sin'", "argument in parentheses"}));
  EXPECT_TRUE(
      FailsAt(kHead + "f = [x2, sin(x1, x2)]\nh = x1\n", 3, 16, {"'sin' takes one argument"}));
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, x1^x2]\nh = x1\n", 3, 13, {"exponent must be a number"}));
  EXPECT_TRUE(
      FailsAt(kHead + "f = [x2, x1^100000]\nh = x1\n", 3, 13, {"exponent", "out of range"}));
}

TEST(ParseDiagnostics, ExponentLimitHoldsAfterGiNaCFoldsPowers) {
  // Found by fuzz/fuzz_parse.cpp: GiNaC folds (b^p)^q into b^(p*q), so each written exponent
  // was within the limit but the model became 1/(x1+1)^1000000000 and the zero test hung.
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, 1/((((x1+1)^1000)^1000)^1000)]\nh = x1\n", 3, 28,
                      {"exponent out of range", "1000000", "limit 1000"}));
  // Integer powers distribute over products: ((2*x1)^1000)^1000 would compute 2^1000000.
  EXPECT_TRUE(
      FailsAt(kHead + "f = [x2, ((2*x1)^1000)^1000]\nh = x1\n", 3, 24, {"exponent out of range"}));
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, (1e400)^1000]\nh = x1\n", 3, 18, {"number too large"}));
  // Within the limit after folding: accepted.
  const Model m = Parse(kHead + "f = [x2, (x1^10)^100]\nh = x1\n");
  EXPECT_TRUE(m.f[1].is_equal(GiNaC::pow(Sym(m, "x1"), 1000))) << m.f[1];
}

TEST(ParseDiagnostics, NumericFactorsOfPowersAreBounded) {
  // Found by fuzz/fuzz_parse.cpp (timeouts): GiNaC pulls the numeric content out of a sum
  // raised to an integer power and raises it on the spot, here (10^-400)^999 and then that
  // number again to the power 999.
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, (2*(1e400*x1 + 5e-400)^999 - 400)^999]\nh = x1\n", 3, 33,
                      {"number too large"}));
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, 1/(1e400*x1 + 1e-400)^999]\nh = x1\n", 3, 32,
                      {"number too large"}));
  // A sum with a small content is not affected, however large its other coefficients.
  EXPECT_NO_THROW(
      parse_model(kHead + "f = [x2, 1/(x1 + 1)^1000 + (sin(x1) + 1e400)^999]\nh = x1\n", kFile));
}

TEST(ParseDiagnostics, ExactEvaluationSizeIsBounded) {
  // Evaluating this exactly at a rational point needs numbers of tens of millions of digits.
  std::string big = "1";
  for (int k = 1; k <= 16; ++k) big += "*(1e400*x2 + " + std::to_string(k) + ")^999";
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, -x1]\nh = [x1, " + big + "]\n", 4, 10,
                      {"expression too large", "binary digits"}));
  // One such factor is fine.
  EXPECT_NO_THROW(parse_model(kHead + "f = [x2, -x1]\nh = [x1, (1e400*x2 + 1)^999]\n", kFile));
}

// ---- expressions -----------------------------------------------------------------------------

TEST(ParseDiagnostics, NonNumericParameterDefaultNamesTheState) {
  EXPECT_TRUE(FailsAt(kHead + "params a = x1\nf = [x2, -a*x1]\nh = [x1]\n", 3, 12,
                      {"default of parameter 'a'", "must be a number", "state 'x1'"}));
  EXPECT_TRUE(FailsAt(kHead + "params k, a = 2*k\nf = [x2, -a*x1]\nh = [x1]\n", 3, 15,
                      {"default of parameter 'a'", "parameter 'k'"}));
  EXPECT_TRUE(FailsAt(kHead + "params a = sqrt(-1)\nf = [x2, -a*x1]\nh = [x1]\n", 3, 12,
                      {"default of parameter 'a'", "real number"}));
}

TEST(ParseDiagnostics, ParameterDefaultsThatCannotBeEvaluatedReliably) {
  // Found while fuzzing: CLN threw floating_point_underflow_exception out of parse_model for
  // exp(-10^400), and silently returned exp(10^400) = 1, sin(10^400) = 0, tanh(10^400) = 0.
  EXPECT_TRUE(FailsAt(kHead + "params a = exp(-10^400)\nf = [x2, -a*x1]\nh = x1\n", 3, 12,
                      {"default of parameter 'a'", "exp()", "10^6"}));
  EXPECT_TRUE(
      FailsAt(kHead + "params a = 1 + sin(10^400)\nf = [x2, -a*x1]\nh = x1\n", 3, 12, {"sin()"}));
  EXPECT_TRUE(FailsAt(kHead + "params a = exp(exp(exp(exp(10))))\nf = [x2, -a*x1]\nh = x1\n", 3, 12,
                      {"exp()"}));
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, -x1]\nh = x1\ndomain x1 in [0, tanh(10^400)]\n", 5, 18,
                      {"domain bound", "tanh()"}));
  // Rounded but reliable defaults are accepted.
  const Model m = Parse(
      kHead + "params a = exp(20), b = log(10^400), c = 4*atan(1)\nf = [x2, -a*x1]\nh = x1\n");
  ASSERT_EQ(m.params.size(), 3u);
  EXPECT_LT(GiNaC::abs(*m.params[2].value - numeric(314159265358979, 100000000000000)),
            numeric(1, 1000000000));
}

TEST(ParseDiagnostics, ComplexConstantsAreRejected) {
  // I and Pi cannot be named, but sqrt(-1) and log(-2) still produce I; the model must be real.
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, sqrt(-1)*x1]\nh = x1\n", 3, 10, {"f[2] is not real"}));
  EXPECT_TRUE(
      FailsAt(kHead + "f = [x2, -x1]\nh = [x1, x2 + log(-2)]\n", 4, 10, {"h[2] is not real"}));
  // Found by fuzz/fuzz_parse.cpp: printing this expression in the message overflowed the stack.
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, sqrt(-1) + 11/(sin(x1)^0 - 11/(sin(x1)))]\nh = x1\n", 3, 10,
                      {"f[2] is not real"}));
  // Complex intermediate values that cancel are fine; Pi from atan(1) is real.
  const Model m = Parse(kHead + "f = [x2, sqrt(-1)^2*x1 + 4*atan(1)]\nh = x1\n");
  EXPECT_TRUE(Same(m.f[1], -Sym(m, "x1") + GiNaC::Pi)) << m.f[1];
  // GiNaC's I^2 = -1 does not pass numeric::is_real(); it is still the real number -1.
  const Model p = Parse(
      kHead + "params a = sqrt(-1)^2\nf = [x2, a*x1]\nh = x1\ndomain x1 in [sqrt(-1)^2, 1]\n");
  ASSERT_TRUE(p.params[0].value.has_value());
  EXPECT_EQ(*p.params[0].value, numeric(-1));
  EXPECT_TRUE(p.params[0].value->is_rational());
  EXPECT_EQ(p.domain.at("x1").lo, numeric(-1));
}

TEST(ParseDiagnostics, UnsupportedFunction) {
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, asin(x1)]\nh = [x1]\n", 3, 10,
                      {"unsupported function 'asin'", "supported:", "sin"}));
  EXPECT_TRUE(
      FailsAt(kHead + "f = [x2, pow(x1, 2)]\nh = [x1]\n", 3, 10, {"unsupported function 'pow'"}));
}

TEST(ParseDiagnostics, DivisionByLiteralZero) {
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, x1/0]\nh = [x1]\n", 3, 12, {"division by zero"}));
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, 0^-1]\nh = [x1]\n", 3, 11, {"division by zero"}));
  // Found by fuzz/fuzz_parse.cpp (a leak inside GiNaC when it throws for 0^0).
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, (x1 - x1)^-0]\nh = [x1]\n", 3, 19, {"0^0 is undefined"}));
}

TEST(ParseDiagnostics, DivisionByAnExpressionThatIsIdenticallyZero) {
  // x1 - x1 collapses to 0 as it is built.
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, 1/(x1 - x1)]\nh = [x1]\n", 3, 11, {"division by zero"}));
  // A trigonometric identity is only found by the zero test.
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, 1/(sin(x1)^2 + cos(x1)^2 - 1)]\nh = [x1]\n", 3, 11,
                      {"division by an expression that is identically zero"}));
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, x2]\nh = [x1 + (exp(x1)*exp(-x1) - 1)^-2]\n", 4, 33,
                      {"identically zero"}));
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, x2]\nh = [x1 + 1/(tan(x1)*cos(x1) - sin(x1))]\n", 4, 12,
                      {"identically zero"}));
  // GiNaC folds exp(2*x1) - exp(x1)^2 to 0 while building, so this is caught at once.
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, x2]\nh = [x1 + (exp(2*x1) - exp(x1)^2)^-2]\n", 4, 34,
                      {"division by zero", "negative power"}));
  // Not identically zero (x1 < 0 is in the default box): accepted.
  EXPECT_NO_THROW(parse_model(kHead + "f = [x2, x2]\nh = [1/(sqrt(x1^2) - x1)]\n", kFile));
}

TEST(ParseDiagnostics, DivisorsAreZeroTestedFactorByFactor) {
  // Found by fuzz/fuzz_parse.cpp (a timeout): the divisor (5e400*x1 + 1.1e-40)^-999 is tiny, so
  // it passed the numeric zero test, and trying to prove it zero then took minutes.
  const Model m =
      Parse("model m\nstates x1\nf = [(2*x1)^10 / (5e400*x1 + 1.1e-40)^-999]\nh = x1\n");
  EXPECT_EQ(m.n(), 1u);
  EXPECT_NO_THROW(parse_model(kHead + "f = [x2, 1/(1e-60*x1 + 1e-60)^999]\nh = x1\n", kFile));
  // exp never vanishes; atan and tanh vanish exactly where their argument does.
  EXPECT_NO_THROW(parse_model(kHead + "f = [x2, 1/exp(-(x1 + 1)^10)]\nh = x1\n", kFile));
  EXPECT_NO_THROW(
      parse_model(kHead + "f = [x2, 1/atan((1e300*x1 + 1e-40)^-999)]\nh = x1\n", kFile));
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, 1/atan(sin(x1)^2 + cos(x1)^2 - 1)]\nh = x1\n", 3, 11,
                      {"identically zero"}));
  // The factor that vanishes is named.
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, 1/(x1*(sin(x1)^2 + cos(x1)^2 - 1)^3)]\nh = x1\n", 3, 11,
                      {"identically zero", "cos(x1)^2+sin(x1)^2-1"}));
}

TEST(ParseDiagnostics, DivisorNotRealAnywhere) {
  // Found by fuzz/fuzz_parse.cpp (a timeout): a divisor with no real value at any sample point
  // sent the zero test into a symbolic proof that ran for minutes.
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, 1/sin(x1 + sin(-1)^(1/2))]\nh = x1\n", 3, 11,
                      {"not real anywhere", "domain"}));
  // The shape the fuzzer found (reduced): sin(-13)^(11/10) is not real.
  EXPECT_TRUE(
      FailsAt(kHead + "f = [x2, x1^2 - 11/sin(2*x1 - 6*x1/sin(-13)^1.1 + sin(x2)^21)]\nh = x1\n", 3,
              19, {"not real anywhere"}));
  // sqrt(b) vanishes where b does, so only b is tested; real somewhere is enough.
  EXPECT_NO_THROW(parse_model(kHead + "f = [x2, 1/sqrt(x1 - 10) + 1/log(x1)]\nh = x1\n", kFile));
}

TEST(ParseDiagnostics, HugeFunctionArguments) {
  // Found by fuzz/fuzz_parse.cpp (a timeout and a wrong diagnostic): sin(x2 - 5^1000) rounds to
  // 0 at every point, so the zero test declared the divisor identically zero, slowly.
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, 1/sin(x2 - 5^1000)]\nh = x1\n", 3, 10,
                      {"argument of sin()", "10^6"}));
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, -x1]\nh = [x1, exp(x1^30)]\ndomain x1 in [0, 10]\n", 4, 10,
                      {"argument of exp()"}));
  // log and atan are fine with any magnitude, and so is exp on a small box.
  EXPECT_NO_THROW(parse_model(
      kHead + "f = [x2, log(1 + x1^2*1e300) + atan(1e300*x1) + exp(x1^15)]\nh = x1\n", kFile));
}

TEST(ParseDiagnostics, LogOfZero) {
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, log(x1 - x1)]\nh = [x1]\n", 3, 10, {"log(0)"}));
}

TEST(Parse, DecimalsAreExact) {
  const Model m = Parse(kHead + "f = [0.1*3*x1 - 0.3*x1 + x2, 0.25*x1]\nh = [x1]\n");
  const Model ref = Parse(kHead + "f = [x2, x1/4]\nh = [x1]\n");
  const auto x1 = Sym(m, "x1"), x2 = Sym(m, "x2");
  // Exactly x2: no floating-point residue such as 1.0e-17*x1.
  EXPECT_TRUE(m.f[0].is_equal(x2)) << m.f[0];
  EXPECT_FALSE(m.f[0].has(x1)) << m.f[0];
  EXPECT_TRUE(m.f[1].is_equal(numeric(1, 4) * x1)) << m.f[1];
  EXPECT_TRUE(GiNaC::ex_to<numeric>(m.f[1].coeff(x1)).is_rational());
  // The same field as the one written with rationals (compared as printed: the two models
  // have their own symbols).
  ASSERT_EQ(ref.f.size(), m.f.size());
  for (std::size_t i = 0; i < m.f.size(); ++i)
    EXPECT_EQ(obsynth::to_string(m.f[i]), obsynth::to_string(ref.f[i]));
}

TEST(Parse, ScientificLiterals) {
  const Model m = Parse(
      "model m\nstates x\nparams a = 1e-3, b = 2.5E+2, c = .5, d = 1., e = 12e0, k = 0.001e3\n"
      "f = [a*x]\nh = x\n");
  ASSERT_EQ(m.params.size(), 6u);
  const numeric want[] = {numeric(1, 1000), numeric(250), numeric(1, 2),
                          numeric(1),       numeric(12),  numeric(1)};
  for (std::size_t i = 0; i < 6; ++i) {
    ASSERT_TRUE(m.params[i].value.has_value()) << m.params[i].name;
    EXPECT_EQ(*m.params[i].value, want[i]) << m.params[i].name;
    EXPECT_TRUE(m.params[i].value->is_rational()) << m.params[i].name;
  }
  // The numeric default is substituted into the fields.
  EXPECT_TRUE(m.f[0].is_equal(numeric(1, 1000) * Sym(m, "x"))) << m.f[0];
  // '1e' without digits is the number 1 followed by the name 'e' (no implicit product).
  EXPECT_TRUE(
      FailsAt("model m\nstates x\nf = [1e*x]\nh = x\n", 3, 7, {"expected ']'", "found 'e'"}));
}

TEST(Parse, MultiLineListsWithComments) {
  const Model m = Parse(
      "# header comment\n"
      "model m   # trailing comment\n"
      "states x1 x2\n"
      "\n"
      "f = [         # the drift\n"
      "  x2,         # first component\n"
      "\n"
      "  # a comment line inside the list\n"
      "  -x1 -\n"
      "    x2/2      # continued expression\n"
      "]\n"
      "h = [\n"
      "  x1\n"
      "]  # done\n");
  const auto x1 = Sym(m, "x1"), x2 = Sym(m, "x2");
  ASSERT_EQ(m.f.size(), 2u);
  EXPECT_TRUE(Same(m.f[0], x2));
  EXPECT_TRUE(Same(m.f[1], -x1 - x2 / 2));
  ASSERT_EQ(m.h.size(), 1u);
  EXPECT_TRUE(Same(m.h[0], x1));
  // Positions of list elements are recorded for later diagnostics.
  ASSERT_TRUE(m.locations.count("f[1]"));
  EXPECT_EQ(m.locations.at("f[1]").line, 9);
  EXPECT_EQ(m.locations.at("f[1]").col, 3);
}

TEST(Parse, CrLfTabsAndCommasBetweenNames) {
  const Model m = Parse(
      "model m\r\nstates x1,\tx2\r\ninputs u\r\nf = [x2,\r\n -x1]\r\ng = [0, u]\r\nh = x1\r\n");
  EXPECT_EQ(m.n(), 2u);
  EXPECT_EQ(m.m(), 1u);
}

TEST(Parse, DeepNestingIsADiagnosticNotACrash) {
  const std::string deep = std::string(10000, '(') + "x1" + std::string(10000, ')');
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, " + deep + "]\nh = [x1]\n", 3, 110,
                      {"nested more than", "levels"}));
  // Unbalanced: found by the bracket check before any recursion.
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, " + std::string(10000, '(') + "]\nh = [x1]\n", 3, 10010,
                      {"']' closes the '('"}));
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, " + std::string(10000, '-') + "x1]\nh = [x1]\n", 3, 209,
                      {"nested more than"}));
  std::string pow_chain;
  for (int i = 0; i < 10000; ++i) pow_chain += "x1^";
  EXPECT_TRUE(
      FailsAt(kHead + "f = [x2, " + pow_chain + "2]\nh = [x1]\n", 3, 607, {"nested more than"}));
  std::string calls;
  for (int i = 0; i < 10000; ++i) calls += "sin(";
  EXPECT_TRUE(
      FailsAt(kHead + "f = [x2, " + calls + "x1" + std::string(10000, ')') + "]\nh = [x1]\n", 3,
              410, {"nested more than"}));
  // Moderate nesting is fine.
  const Model m = Parse(kHead + "f = [x2, " + std::string(60, '(') + "x1" + std::string(60, ')') +
                        "]\nh = [x1]\n");
  EXPECT_TRUE(Same(m.f[1], Sym(m, "x1")));
}

TEST(Parse, NestingLimitIsConfigurable) {
  obsynth::ParseLimits tight;
  tight.max_nesting = 10;
  const std::string text = kHead + "f = [x2, ((((((((((x1))))))))))]\nh = [x1]\n";
  EXPECT_NO_THROW(parse_model(text, kFile));
  EXPECT_THROW(parse_model(text, kFile, tight), UserError);
}

TEST(Parse, CapitalFIsSplitIntoDriftAndInputPart) {
  const Model m = Parse(kHead + "inputs u\nF = [x2 + u*x1, -x1 + (1+x1)*u + u^2]\nh = [x1]\n");
  const auto x1 = Sym(m, "x1"), x2 = Sym(m, "x2"), u = Sym(m, "u");
  ASSERT_EQ(m.f.size(), 2u);
  ASSERT_EQ(m.g.size(), 2u);
  EXPECT_TRUE(Same(m.f[0], x2));
  EXPECT_TRUE(Same(m.f[1], -x1));
  EXPECT_TRUE(Same(m.g[0], u * x1));
  EXPECT_TRUE(Same(m.g[1], (1 + x1) * u + u * u));
  // f + g gives back F.
  const auto F = m.field();
  EXPECT_TRUE(Same(F[1], -x1 + (1 + x1) * u + u * u));
}

TEST(Parse, CapitalFWithoutInputsHasZeroG) {
  const Model m = Parse(kHead + "F = [x2, -x1]\nh = x1\n");
  ASSERT_EQ(m.g.size(), 2u);
  EXPECT_TRUE(m.g[0].is_zero());
  EXPECT_TRUE(m.g[1].is_zero());
}

TEST(Parse, WorkedExampleAndDefaults) {
  const Model m = Parse(
      "model slawinski17\nstates x1 x2\ninputs u\nparams a = 1.5, k\n"
      "f = [ -x2, -x1*x2 ]\ng = [ (1+x1)*u, u ]\nh = [ x1 ]\n");
  EXPECT_EQ(m.name, "slawinski17");
  EXPECT_EQ(m.file, kFile);
  EXPECT_EQ(m.n(), 2u);
  EXPECT_EQ(m.m(), 1u);
  EXPECT_EQ(m.p(), 1u);
  ASSERT_EQ(m.params.size(), 2u);
  EXPECT_EQ(*m.params[0].value, numeric(3, 2));
  EXPECT_FALSE(m.params[1].value.has_value());
  ASSERT_EQ(m.free_params().size(), 1u);
  EXPECT_EQ(m.free_params()[0].get_name(), "k");
  const auto x1 = Sym(m, "x1"), x2 = Sym(m, "x2"), u = Sym(m, "u");
  EXPECT_TRUE(Same(m.f[1], -x1 * x2));
  EXPECT_TRUE(Same(m.g[0], (1 + x1) * u));
  // Without 'g' the input part is zero.
  const Model m2 = Parse(kHead + "f = [x2, -x1]\nh = x1\n");
  EXPECT_TRUE(m2.g[0].is_zero() && m2.g[1].is_zero());
  // Several outputs are allowed; a scalar h is a one-element list.
  EXPECT_EQ(Parse(kHead + "f = [x2, -x1]\nh = [x1, x2]\n").p(), 2u);
  EXPECT_EQ(Parse(kHead + "f = [x2, -x1]\nh = x1\n").p(), 1u);
}

TEST(Parse, SymbolsAreCreatedOnce) {
  const Model m = Parse(kHead + "f = [x2, -x1]\nh = x1\n");
  // GiNaC compares symbols by identity: x2 in f must be the declared state x2.
  EXPECT_TRUE(m.f[0].is_equal(m.states[1]));
  EXPECT_TRUE(m.h[0].is_equal(m.states[0]));
}

// ---- domain ----------------------------------------------------------------------------------

TEST(ParseDomain, Intervals) {
  const Model m =
      Parse(kHead +
            "inputs u\nparams k, a = 2\nf = [x2, -k*x1]\nh = x1\n"
            "domain x1 in [-1, 1], u in [0, 1/2], k in [0.5, 2e1], x2 in [-(3), 2*2]\n");
  ASSERT_EQ(m.domain.size(), 4u);
  EXPECT_EQ(m.domain.at("x1").lo, numeric(-1));
  EXPECT_EQ(m.domain.at("x1").hi, numeric(1));
  EXPECT_EQ(m.domain.at("u").hi, numeric(1, 2));
  EXPECT_EQ(m.domain.at("k").lo, numeric(1, 2));
  EXPECT_EQ(m.domain.at("k").hi, numeric(20));
  EXPECT_EQ(m.domain.at("x2").lo, numeric(-3));
  EXPECT_EQ(m.domain.at("x2").hi, numeric(4));
  // Symbols without a domain get the documented default boxes.
  const Model d = Parse(kHead + "params k\nf = [x2, -k*x1]\nh = x1\n");
  EXPECT_EQ(d.box(Sym(d, "x1")).lo, numeric(-2));
  EXPECT_EQ(d.box(Sym(d, "k")).lo, numeric(1, 2));
}

TEST(ParseDomain, UnknownName) {
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, -x1]\nh = x1\ndomain x1 in [-1, 1], x3 in [0, 1]\n", 5, 23,
                      {"unknown symbol 'x3'", "domain", "did you mean"}));
}

TEST(ParseDomain, EmptyInterval) {
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, -x1]\nh = x1\ndomain x1 in [1, 1]\n", 5, 15,
                      {"empty interval for 'x1'"}));
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, -x1]\nh = x1\ndomain x2 in [2, -1]\n", 5, 15,
                      {"empty interval for 'x2'"}));
}

TEST(ParseDomain, MissingIn) {
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, -x1]\nh = x1\ndomain x1 [-1, 1]\n", 5, 11,
                      {"expected 'in' after 'x1'"}));
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, -x1]\nh = x1\ndomain x1 inside [-1, 1]\n", 5, 11,
                      {"expected 'in'"}));
}

TEST(ParseDomain, OtherErrors) {
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, -x1]\nh = x1\ndomain x1 in [-1, 1], x1 in [0, 1]\n", 5, 23,
                      {"'x1' appears twice"}));
  EXPECT_TRUE(FailsAt(kHead + "params a = 2\nf = [x2, -a*x1]\nh = x1\ndomain a in [0, 1]\n", 6, 8,
                      {"parameter 'a'", "fixed value"}));
  EXPECT_TRUE(FailsAt(kHead + "f = [x2, -x1]\nh = x1\ndomain x1 in [-1, x2]\n", 5, 19,
                      {"domain bound", "state 'x2'"}));
  EXPECT_TRUE(
      FailsAt(kHead + "f = [x2, -x1]\nh = x1\ndomain x1 in [-1 1]\n", 5, 18, {"expected ','"}));
  EXPECT_TRUE(
      FailsAt(kHead + "f = [x2, -x1]\nh = x1\ndomain x1 in -1, 1\n", 5, 14, {"expected '['"}));
}

// A line that ends with ',' continues on the next (design.md §2 keeps statements on one line,
// brackets aside; a long domain needs more than one).
TEST(ParseDomain, ContinuesAfterATrailingComma) {
  const Model m = Parse(kHead +
                        "inputs u\nparams k,\n       a = 2\nf = [x2, -k*x1]\ng = [0, u]\n"
                        "h = x1\ndomain x1 in [-1, 1],   # position\n"
                        "       x2 in [-3, 4],\n\n"
                        "       u in [0, 1/2], k in [0.5, 2]\n");
  ASSERT_EQ(m.params.size(), 2u);
  EXPECT_EQ(*m.params[1].value, numeric(2));
  ASSERT_EQ(m.domain.size(), 4u);
  EXPECT_EQ(m.domain.at("x2").lo, numeric(-3));
  EXPECT_EQ(m.domain.at("u").hi, numeric(1, 2));
  EXPECT_EQ(m.domain.at("k").hi, numeric(2));
  // Name lists and 'nominal' wrap the same way.
  const Model w = Parse(
      "model m\nstates x1,\n  x2\ninputs u,\n v\nF = [x2, -x1 + u*v]\n"
      "h = x1\nnominal u = 1,\n v = 1\n");
  EXPECT_EQ(w.n(), 2u);
  EXPECT_EQ(w.m(), 2u);
  ASSERT_EQ(w.nominal.size(), 2u);
  EXPECT_EQ(w.nominal[1], numeric(1));
}

TEST(ParseDomain, TrailingCommaBeforeAStatementOrTheEnd) {
  const std::string body = kHead + "f = [x2, -x1]\nh = x1\n";
  // Diagnosed at the ',' itself, naming the statement that follows.
  EXPECT_TRUE(FailsAt(body + "domain x1 in [-1, 1],\noption poles = -1, -2\n", 5, 21,
                      {"'domain' line ends with ','", "line 6", "'option'", "remove"}));
  EXPECT_TRUE(FailsAt(kHead + "params k,\nf = [x2, -k*x1]\nh = x1\n", 3, 9,
                      {"'params' line ends with ','", "line 4", "'f' statement"}));
  EXPECT_TRUE(FailsAt("model m\nstates x1 x2,\n\nf = [x2, -x1]\nh = x1\n", 2, 13,
                      {"'states' line ends with ','", "line 4", "'f'"}));
  EXPECT_TRUE(FailsAt(body + "domain x1 in [-1, 1],\n", 5, 21,
                      {"'domain' list ends with ','", "another item"}));
  EXPECT_TRUE(FailsAt(body + "domain x1 in [-1, 1],  # nothing follows", 5, 21,
                      {"'domain' list ends with ','"}));
  // A continued line is still checked item by item, at the item's own position.
  EXPECT_TRUE(FailsAt(body + "domain x1 in [-1, 1],\n  x3 in [0, 1]\n", 6, 3,
                      {"unknown symbol 'x3'", "did you mean"}));
  EXPECT_TRUE(FailsAt(body + "domain x1 in [-1, 1],\n  x2 [0, 1]\n", 6, 6, {"expected 'in'"}));
  // Without the ',' a line break still ends the statement.
  EXPECT_TRUE(
      FailsAt(body + "domain x1 in [-1, 1]\n  x2 in [0, 1]\n", 6, 3, {"unknown keyword 'x2'"}));
}

// ---- diagnostics formatting and files --------------------------------------------------------

TEST(ParseDiagnostics, FormattedLikeGcc) {
  try {
    parse_model(kHead + "f = [x2, -x3]\nh = [x1]\n", "dir/model.sym");
    FAIL() << "parsed";
  } catch (const UserError& e) {
    const std::string s = obsynth::format_diagnostic(e.diagnostics().front());
    EXPECT_EQ(s.rfind("dir/model.sym:3:11: error: unknown symbol 'x3'", 0), 0u) << s;
  }
}

TEST(ParseFiles, UnreadableFileIsAUserError) {
  EXPECT_THROW(obsynth::load_model(std::string(OBSYNTH_SOURCE_DIR) + "/models/does-not-exist.sym"),
               UserError);
}

TEST(ParseFiles, EveryShippedModelParses) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::path(OBSYNTH_SOURCE_DIR) / "models";
  ASSERT_TRUE(fs::is_directory(dir)) << dir;
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().extension() == ".sym") files.push_back(e.path());
  std::sort(files.begin(), files.end());
  ASSERT_FALSE(files.empty());
  for (const auto& f : files) {
    SCOPED_TRACE(f.string());
    try {
      const Model m = obsynth::load_model(f.string());
      EXPECT_FALSE(m.name.empty());
      EXPECT_GE(m.n(), 1u);
      EXPECT_EQ(m.f.size(), m.n());
      EXPECT_EQ(m.g.size(), m.n());
      EXPECT_GE(m.p(), 1u);
      EXPECT_EQ(m.file, f.string());
    } catch (const UserError& e) {
      ADD_FAILURE() << e.what();
    }
  }
}

}  // namespace
