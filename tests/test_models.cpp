// Every bundled model against the hand derivations in tests/expectations/models.json
// (derived and checked by substitution independently of obsynth; see each model's header).
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <fstream>
#include <set>

#include "analysis/analysis.hpp"
#include "front/parse.hpp"
#include "support/expect.hpp"

using namespace obsynth;
using nlohmann::json;
using obsynth::testing::oracle_box;
using obsynth::testing::OracleBox;
using obsynth::testing::parse_with;
using obsynth::testing::same;

namespace {

json expectations() {
  std::ifstream in(std::string(OBSYNTH_SOURCE_DIR) + "/tests/expectations/models.json");
  return json::parse(in);
}

std::vector<std::string> model_names() {
  std::vector<std::string> names;
  for (const auto& m : expectations()) names.push_back(m["model"]);
  return names;
}

class BundledModel : public ::testing::TestWithParam<std::string> {};

TEST_P(BundledModel, MatchesHandDerivation) {
  json expected;
  for (const auto& m : expectations())
    if (m["model"] == GetParam()) expected = m;
  const Model model =
      load_model(std::string(OBSYNTH_SOURCE_DIR) + "/models/" + GetParam() + ".sym");
  EXPECT_EQ(model.name, GetParam());
  const Analysis a = analyse(model);
  const CanonicalForm& cf = a.canonical;
  std::vector<GiNaC::symbol> syms = model.all_symbols();
  syms.push_back(cf.y[0]);
  for (const auto& z : cf.z) syms.push_back(z);
  // The oracle samples the model's own symbols in its domain box (the others in its default).
  const OracleBox box = oracle_box(model);
  auto parse_vec = [&](const json& v) {
    ExVec out;
    for (const auto& s : v) out.push_back(parse_with(s.get<std::string>(), syms));
    return out;
  };

  ASSERT_EQ(model.n(), expected["n"].get<std::size_t>());
  EXPECT_EQ(a.observability.generic_rank, expected["generic_rank"].get<std::size_t>());

  // Rank-drop factors, each up to a nonzero constant.
  const ExVec want_drop = parse_vec(expected["rank_drop"]);
  ASSERT_EQ(a.observability.rank_drop.size(), want_drop.size());
  for (const auto& w : want_drop) {
    bool found = false;
    for (const auto& got : a.observability.rank_drop) {
      const GiNaC::ex q = GiNaC::normal(got / w);
      found |= GiNaC::is_a<GiNaC::numeric>(q) && !q.is_zero();
    }
    EXPECT_TRUE(found) << "rank-drop factor " << w;
  }

  if (expected["r"].is_null()) {
    EXPECT_FALSE(cf.applicable);
    return;
  }
  ASSERT_TRUE(cf.applicable) << cf.not_applicable;
  EXPECT_TRUE(same(cf.r, parse_vec(expected["r"]), box));

  std::set<std::pair<std::size_t, std::size_t>> want_drift, got_drift;
  for (const auto& p : expected["drift_fail"])
    want_drift.insert({p[0].get<std::size_t>(), p[1].get<std::size_t>()});
  for (const auto& b : cf.drift)
    if (!b.holds()) got_drift.insert({b.i, b.j});
  EXPECT_EQ(got_drift, want_drift);
  std::set<std::size_t> want_input, got_input;
  for (const auto& j : expected["input_fail"]) want_input.insert(j.get<std::size_t>());
  for (const auto& b : cf.input)
    if (!b.holds()) got_input.insert(b.j);
  EXPECT_EQ(got_input, want_input);

  EXPECT_EQ(cf.linearizable, expected["linearizable"].get<bool>());
  if (!expected["linearizable"].get<bool>()) return;
  ASSERT_EQ(cf.T_kind, Availability::symbolic) << cf.T_note;
  EXPECT_TRUE(same(cf.T, parse_vec(expected["T"]), box));
  ASSERT_EQ(cf.l_kind, Availability::symbolic) << cf.l_note;
  EXPECT_TRUE(same(cf.l, parse_vec(expected["l"]), box));
  ASSERT_EQ(cf.T_inverse_kind, Availability::symbolic) << cf.T_inverse_note;
  EXPECT_TRUE(same(cf.T_inverse, parse_vec(expected["T_inverse"]), box));
}

INSTANTIATE_TEST_SUITE_P(Models, BundledModel, ::testing::ValuesIn(model_names()));

}  // namespace
