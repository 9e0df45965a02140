// Reports: the JSON keys of the machine interface, every expression string reading back
// through GiNaC's parser to the same expression, and byte-identical output between runs.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "analysis/analysis.hpp"
#include "app/report.hpp"
#include "front/parse.hpp"
#include "support/expect.hpp"

using namespace obsynth;
using nlohmann::json;
using obsynth::testing::parse_with;

namespace {

std::string model_path(const std::string& name) {
  return std::string(OBSYNTH_SOURCE_DIR) + "/models/" + name + ".sym";
}

std::string json_report(const std::string& name) {
  const Analysis a = analyse(load_model(model_path(name)));
  ReportOptions ro;
  ro.timings = false;
  return render_report(a, ReportFormat::json, ro);
}

TEST(JsonReport, HasTheDocumentedKeys) {
  const json j = json::parse(json_report("slawinski17"));
  for (const char* key :
       {"model", "states", "inputs", "lie_derivatives", "observability", "r", "frame", "conditions",
        "linearizable", "T", "T_inverse", "l", "timings_ms"})
    EXPECT_TRUE(j.contains(key)) << key;
  for (const char* key : {"n", "generic_rank", "rank_drop", "undefined"})
    EXPECT_TRUE(j["observability"].contains(key)) << key;
  for (const char* key : {"drift", "input", "complete"})
    EXPECT_TRUE(j["conditions"].contains(key)) << key;
  const json& d = j["conditions"]["drift"][0];
  for (const char* key : {"i", "j", "holds", "verdict", "residual"})
    EXPECT_TRUE(d.contains(key)) << key;
  EXPECT_EQ(j["conditions"]["input"][0]["verdict"], "proved");
  EXPECT_TRUE(j["linearizable"].get<bool>());
}

TEST(JsonReport, FailingConditionsCarryResiduals) {
  const json j = json::parse(json_report("rayleigh"));
  const json& d = j["conditions"]["drift"][0];
  EXPECT_FALSE(d["holds"].get<bool>());
  EXPECT_EQ(d["verdict"], "nonzero");
  EXPECT_EQ(d["residual"], json::array({"0", "-2*x2"}));
  EXPECT_TRUE(j["T"].is_null());
  EXPECT_FALSE(j["linearizable"].get<bool>());
}

// Collects every string that is an expression in the report.
void expression_strings(const json& j, const std::string& key, std::vector<std::string>& out) {
  static const std::set<std::string> expr_keys = {
      "f",     "g", "h",     "lie_derivatives", "matrix",     "det", "rank_drop", "undefined",
      "value", "r", "frame", "residual",        "base_point", "T",   "T_inverse", "l"};
  if (j.is_string() && expr_keys.count(key)) out.push_back(j.get<std::string>());
  if (j.is_array())
    for (const auto& e : j) expression_strings(e, key, out);
  if (j.is_object())
    for (const auto& [k, v] : j.items()) expression_strings(v, k, out);
}

class RoundTrip : public ::testing::TestWithParam<std::string> {};

TEST_P(RoundTrip, EveryExpressionReadsBack) {
  const Model m = load_model(model_path(GetParam()));
  const Analysis a = analyse(m);
  const json j = report_json(a);
  std::vector<std::string> strings;
  expression_strings(j, "", strings);
  ASSERT_FALSE(strings.empty());
  std::vector<GiNaC::symbol> syms = m.all_symbols();
  syms.push_back(a.canonical.y[0]);
  for (const auto& z : a.canonical.z) syms.push_back(z);
  for (const auto& s : strings) {
    GiNaC::ex e;
    ASSERT_NO_THROW(e = parse_with(s, syms)) << s;
    // Printing the parsed expression again gives the same text: the string is canonical.
    EXPECT_EQ(to_string(e), s);
  }
  // And the strings denote the pipeline's expressions (not just some expression).
  for (std::size_t i = 0; i < a.canonical.T.size(); ++i)
    EXPECT_TRUE(
        obsynth::testing::same(parse_with(j["T"][i].get<std::string>(), syms), a.canonical.T[i]));
}

INSTANTIATE_TEST_SUITE_P(Models, RoundTrip,
                         ::testing::Values("slawinski17", "triangular4", "flexible_joint", "cstr",
                                           "jamesbaras_sin", "lorenz", "garcia14",
                                           "stuart_landau"));

TEST(Determinism, SameBytesAfterCreatingUnrelatedSymbols) {
  const std::string first = json_report("triangular4");
  // Unrelated symbols and expressions shift GiNaC's hash seeds and term order.
  std::vector<GiNaC::symbol> noise;
  for (int i = 0; i < 500; ++i) noise.emplace_back("noise" + std::to_string(i));
  GiNaC::ex junk = 0;
  for (const auto& s : noise) junk += GiNaC::pow(s, 3) * GiNaC::sin(s);
  (void)GiNaC::expand(junk * junk);
  EXPECT_EQ(json_report("triangular4"), first);
  EXPECT_EQ(json_report("cstr"), json_report("cstr"));
}

TEST(TextReports, MentionWhatFails) {
  const Analysis a = analyse(load_model(model_path("duffing_semiactive")));
  const std::string text = render_report(a, ReportFormat::text);
  EXPECT_NE(text.find("C3 [g, tau_1] = 0"), std::string::npos);
  EXPECT_NE(text.find("FAILS"), std::string::npos);
  const std::string md = render_report(a, ReportFormat::markdown);
  EXPECT_NE(md.find("| C3: $[g, \\tau_{1}] = 0$ | FAILS"), std::string::npos);
  const std::string tex = render_report(a, ReportFormat::latex);
  EXPECT_NE(tex.find("\\begin{align*}"), std::string::npos);
  EXPECT_NE(tex.find("\\neq 0"), std::string::npos);
}

}  // namespace
