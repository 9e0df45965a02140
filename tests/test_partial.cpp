// Partial analyses: a budget stop keeps the results of the stages that completed, marks the
// stopped stage and those after it, and the report says so in every format. Stops are injected
// at a stage's beginning through AnalysisOptions::on_stage (a listener that throws), so the
// stage that stops is known exactly; expected values come from the hand derivation in
// models/triangular4.sym.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <new>

#include "analysis/analysis.hpp"
#include "app/report.hpp"
#include "front/parse.hpp"
#include "symbolic/expr_print.hpp"

using namespace obsynth;

namespace {

std::string model_path(const std::string& name) {
  return std::string(OBSYNTH_SOURCE_DIR) + "/models/" + name + ".sym";
}

// Options whose on_stage listener stops `stage` as it begins, by throwing `stop`.
template <class Stop>
AnalysisOptions stopping_at(const std::string& stage, Stop stop) {
  AnalysisOptions o;
  o.keep_partial = true;
  o.budget.max_memory_bytes = std::size_t{256} << 20;
  o.on_stage = [stage, stop](const std::string& s) {
    if (s == stage) throw stop;
  };
  return o;
}

std::vector<std::string> statuses(const Analysis& a) {
  std::vector<std::string> out;
  for (const auto& s : a.stages) out.push_back(s.name + " " + stage_status_name(s.status));
  return out;
}

}  // namespace

TEST(PartialAnalysis, CompleteRunListsEveryStageCompleted) {
  const Analysis a = analyse(load_model(model_path("triangular4")));
  EXPECT_TRUE(a.complete());
  EXPECT_EQ(statuses(a),
            (std::vector<std::string>{"lie completed", "observability completed", "frame completed",
                                      "conditions completed", "diffeomorphism completed"}));
}

TEST(PartialAnalysis, FrameStopKeepsTheRank) {
  const Model m = load_model(model_path("triangular4"));
  const Analysis a =
      analyse(m, stopping_at("frame", BudgetExceeded("frame", "exceeded its time budget of 1 s")));
  EXPECT_FALSE(a.complete());
  ASSERT_NE(a.stopped_stage(), nullptr);
  EXPECT_EQ(a.stopped_stage()->name, "frame");
  EXPECT_EQ(a.stopped_stage()->reason, "exceeded its time budget of 1 s");
  EXPECT_EQ(statuses(a),
            (std::vector<std::string>{"lie completed", "observability completed", "frame stopped",
                                      "conditions not run", "diffeomorphism not run"}));
  // Hand derivation: L_f h = x2, rank 4, det O = 1.
  EXPECT_EQ(a.observability.generic_rank, 4u);
  EXPECT_TRUE((a.observability.det - 1).is_zero());
  ASSERT_EQ(a.observability.lie[0].size(), 4u);
  EXPECT_TRUE((a.observability.lie[0][1] - m.states[1]).is_zero());
  // Nothing of the stopped stage survives.
  EXPECT_TRUE(a.canonical.r.empty());
  EXPECT_TRUE(a.canonical.frame.empty());
  EXPECT_TRUE(a.lost("frame"));
  EXPECT_TRUE(a.lost("diffeomorphism"));
  EXPECT_FALSE(a.lost("observability"));
}

TEST(PartialAnalysis, MemoryStopInDiffeomorphismKeepsTheBracketVerdicts) {
  const Analysis a = analyse(load_model(model_path("triangular4")),
                             stopping_at("diffeomorphism", std::bad_alloc()));
  ASSERT_NE(a.stopped_stage(), nullptr);
  EXPECT_EQ(a.stopped_stage()->name, "diffeomorphism");
  EXPECT_EQ(a.stopped_stage()->reason,
            "exceeded its memory budget of 256 MiB (raise it with --max-memory)");
  // Hand derivation: r = [0, 0, 0, 1], every bracket condition holds.
  ASSERT_EQ(a.canonical.r.size(), 4u);
  for (std::size_t i = 0; i < 4; ++i) EXPECT_TRUE((a.canonical.r[i] - (i == 3 ? 1 : 0)).is_zero());
  EXPECT_TRUE(a.canonical.linearizable);
  EXPECT_TRUE(a.canonical.T.empty());
}

TEST(PartialAnalysis, WithoutKeepPartialTheStopThrows) {
  AnalysisOptions o = stopping_at("conditions", std::bad_alloc());
  o.keep_partial = false;
  try {
    (void)analyse(load_model(model_path("triangular4")), o);
    FAIL() << "no BudgetExceeded";
  } catch (const BudgetExceeded& e) {
    EXPECT_EQ(e.stage(), "conditions");
    ASSERT_EQ(e.diagnostics().size(), 1u);
    EXPECT_EQ(e.diagnostics()[0].message,
              "stage 'conditions' exceeded its memory budget of 256 MiB (raise it with "
              "--max-memory)");
  }
}

TEST(PartialAnalysis, StagesAnUnobservableModelDoesNotNeed) {
  // x1' = 0, x2' = x1, y = x1: L_f h = 0, so rank O = 1 < 2.
  const Analysis a =
      analyse(parse_model("model flat\nstates x1 x2\nf = [0, x1]\nh = [x1]\n", "flat.sym"));
  EXPECT_TRUE(a.complete());
  EXPECT_EQ(a.observability.generic_rank, 1u);
  EXPECT_EQ(statuses(a), (std::vector<std::string>{"lie completed", "observability completed",
                                                   "frame not needed", "conditions not needed",
                                                   "diffeomorphism not needed"}));
  EXPECT_EQ(a.stages[2].reason, a.canonical.not_applicable);
}

TEST(PartialAnalysis, CheckpointsOfferTheStagesBeforeEach) {
  AnalysisOptions o;
  o.checkpoint_reason = "killed";
  std::vector<std::string> seen;
  o.on_checkpoint = [&](const Analysis& p) {
    const StageOutcome* s = p.stopped_stage();
    ASSERT_NE(s, nullptr);
    EXPECT_EQ(s->reason, "killed");
    std::size_t completed = 0;
    for (const auto& st : p.stages) completed += st.status == StageStatus::completed;
    seen.push_back(fmt::format("{} after {}", s->name, completed));
    if (s->name == "frame") EXPECT_EQ(p.observability.generic_rank, 4u);
    if (s->name == "lie") EXPECT_TRUE(p.observability.lie.empty());
  };
  const Analysis a = analyse(load_model(model_path("triangular4")), o);
  EXPECT_TRUE(a.complete());
  EXPECT_EQ(seen, (std::vector<std::string>{"lie after 0", "observability after 1", "frame after 2",
                                            "conditions after 3", "diffeomorphism after 4"}));
}

TEST(PartialReport, EveryFormatShowsTheCompletedStagesAndTheStop) {
  const Analysis a =
      analyse(load_model(model_path("triangular4")),
              stopping_at("frame", BudgetExceeded("frame", "exceeded its time budget of 1 s")));
  ReportOptions ro;
  ro.timings = false;
  const std::string text = render_report(a, ReportFormat::text, ro);
  EXPECT_NE(text.find("generic rank 4 of n = 4"), std::string::npos) << text;
  EXPECT_NE(text.find("frame: stopped: exceeded its time budget of 1 s"), std::string::npos);
  EXPECT_NE(text.find("conditions: not run"), std::string::npos);
  EXPECT_EQ(text.find("Linearization by output injection"), std::string::npos);
  const std::string md = render_report(a, ReportFormat::markdown, ro);
  EXPECT_NE(md.find("| frame | stopped | exceeded its time budget of 1 s |"), std::string::npos);
  EXPECT_NE(md.find("generic rank **4**"), std::string::npos);
  const std::string tex = render_report(a, ReportFormat::latex, ro);
  EXPECT_NE(tex.find("\\texttt{frame}: stopped"), std::string::npos);
  EXPECT_NE(tex.find("\\operatorname{rank} O &= 4"), std::string::npos);
  EXPECT_EQ(tex.find("\\begin{itemize}\n  \\item $[\\tau"), std::string::npos);

  const auto j = nlohmann::json::parse(render_report(a, ReportFormat::json, ro));
  EXPECT_EQ(j["complete"], false);
  EXPECT_EQ(j["observability"]["generic_rank"], 4);
  EXPECT_TRUE(j["r"].is_null());
  EXPECT_TRUE(j["conditions"].is_null());
  EXPECT_TRUE(j["T"].is_null());
  ASSERT_EQ(j["stages"].size(), 5u);
  EXPECT_EQ(j["stages"][1],
            nlohmann::json({{"name", "observability"}, {"status", "completed"}, {"reason", ""}}));
  EXPECT_EQ(j["stages"][2]["status"], "stopped");
  EXPECT_EQ(j["stages"][4]["status"], "not run");
}

TEST(PartialReport, CompleteReportsAreUnchangedButForTheStageList) {
  const Analysis a = analyse(load_model(model_path("triangular4")));
  ReportOptions ro;
  ro.timings = false;
  EXPECT_EQ(render_report(a, ReportFormat::text, ro).find("Report incomplete"), std::string::npos);
  const auto j = nlohmann::json::parse(render_report(a, ReportFormat::json, ro));
  EXPECT_EQ(j["complete"], true);
  for (const auto& s : j["stages"]) EXPECT_EQ(s["status"], "completed");
}

TEST(PrintCache, SameTextAsWithoutItEvenForShortLivedExpressions) {
  const GiNaC::symbol x("x"), y("y");
  std::vector<std::string> plain, latex;
  for (int i = 0; i < 200; ++i) {
    const GiNaC::ex e = GiNaC::pow(x, i) * y + i;  // a new object each time
    plain.push_back(to_string(e));
    latex.push_back(to_latex(e));
  }
  PrintCache cache;
  PrintCache::Use use(cache);
  for (int round = 0; round < 2; ++round)
    for (int i = 0; i < 200; ++i) {
      // Temporaries die after each call unless the cache holds them: a reused address must
      // not return another expression's text.
      EXPECT_EQ(to_string(GiNaC::pow(x, i) * y + i), plain[i]);
      EXPECT_EQ(to_latex(GiNaC::pow(x, i) * y + i), latex[i]);
    }
}
