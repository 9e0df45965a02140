// The application layer: simulate (convergence, divergence detection), the SVG writer,
// auto's choice and its messages, and write_output_dir's atomicity. Oracles are written here
// independently of the code under test (a tiny XML tag matcher, file-system inspection).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <unistd.h>

#include "analysis/analysis.hpp"
#include "app/output_dir.hpp"
#include "app/simulate.hpp"
#include "app/svg_plot.hpp"
#include "app/synthesize.hpp"
#include "front/diagnostics.hpp"
#include "front/parse.hpp"

using namespace obsynth;
namespace fs = std::filesystem;

namespace {

const char* kSeed003 = R"(model slawinski17
states x1 x2
inputs u
f = [ -x2, -x1*x2 ]
g = [ (1+x1)*u, u ]
h = [ x1 ]
domain x1 in [-2, 2], x2 in [-2, 2], u in [-1, 1]
)";

// Rayleigh with y = x1: tau_2 = [1, 1 - x2^2] is not constant, so [tau_1, tau_2] != 0 and the
// canonical form does not exist (seed 003 Lemma 1, condition C2).
const char* kRayleigh = R"(model rayleigh
states x1 x2
inputs u
f = [ x2, -x1 + x2 - x2^3/3 ]
g = [ 0, u ]
h = [ x1 ]
)";

double final_error(const SimulationResult& r) {
  double e = 0;
  for (size_t i = 0; i < r.names.size(); ++i)
    e = std::max(e, std::abs(r.x.back()[i] - r.xh.back()[i]));
  return e;
}

SimulationResult run_seed003(Sampling s, double dt, const std::string& u) {
  SimulationOptions o;
  o.u_text = u;
  o.x0 = {0.5, -0.5};
  o.xhat0 = {0, 0};
  o.t_end = 10;
  o.dt = dt;
  o.sampling = s;
  return simulate(analyse(parse_model(kSeed003, "seed003.sym")), o);
}

TEST(Simulate, ContinuousConverges) {
  const auto r = run_seed003(Sampling::continuous, 1e-3, "sin(t)");
  EXPECT_TRUE(r.diverged.empty()) << r.diverged;
  EXPECT_NEAR(r.t.back(), 10, 1e-9);
  EXPECT_LT(final_error(r), 1e-6);
}

// ZOH holds u over a step: the steady error is first order in dt, so halving dt roughly halves
// it, and it is far below the initial error.
TEST(Simulate, ZohErrorIsFirstOrder) {
  const double e1 = final_error(run_seed003(Sampling::zoh, 2e-2, "sin(t)"));
  const double e2 = final_error(run_seed003(Sampling::zoh, 1e-2, "sin(t)"));
  EXPECT_LT(e1, 2e-2 * 10);  // C dt with C of the order of |du/dt| times the gain
  EXPECT_GT(e2, 0);
  EXPECT_GT(e1 / e2, 1.5);
  EXPECT_LT(e1 / e2, 2.5);
}

TEST(Simulate, DivergenceStopsWithTimeAndSystem) {
  const auto r = run_seed003(Sampling::continuous, 1e-3, "20 - 2*sqrt((t-5)^2)");
  ASSERT_FALSE(r.diverged.empty());
  EXPECT_NE(r.diverged.find("left the finite numbers at t = 0.7"), std::string::npos) << r.diverged;
  EXPECT_TRUE(r.diverged.find("plant") != std::string::npos ||
              r.diverged.find("observer") != std::string::npos);
  ASSERT_FALSE(r.t.empty());
  EXPECT_LT(r.t.back(), 0.8);
  for (size_t k = 0; k < r.t.size(); ++k)
    for (size_t i = 0; i < 2; ++i)
      ASSERT_TRUE(std::isfinite(r.x[k][i]) && std::isfinite(r.xh[k][i]));
  // The CSV ends at the last finite sample: its last row's time is r.t.back().
  std::istringstream csv(r.csv);
  std::string line, last;
  std::getline(csv, line);
  EXPECT_EQ(line, "t,x1,x2,x1_hat,x2_hat");
  size_t rows = 0;
  while (std::getline(csv, line))
    if (!line.empty()) last = line, ++rows;
  EXPECT_EQ(rows, r.t.size());
  EXPECT_NEAR(std::stod(last.substr(0, last.find(','))), r.t.back(), 1e-9);
  EXPECT_EQ(last.find("nan"), std::string::npos);
}

// Checks that every tag is closed in order; returns the number of elements, -1 if unbalanced.
int balanced_elements(const std::string& xml) {
  std::vector<std::string> open;
  int elements = 0;
  for (size_t p = xml.find('<'); p != std::string::npos; p = xml.find('<', p + 1)) {
    const size_t q = xml.find('>', p);
    if (q == std::string::npos) return -1;
    const std::string tag = xml.substr(p + 1, q - p - 1);
    if (tag.empty() || tag[0] == '?' || tag[0] == '!') continue;
    const std::string name =
        tag.substr(tag[0] == '/', tag.find_first_of(" \t\n/", 1) - (tag[0] == '/'));
    if (tag[0] == '/') {
      if (open.empty() || open.back() != name) return -1;
      open.pop_back();
    } else if (tag.back() != '/') {
      open.push_back(name), ++elements;
    } else {
      ++elements;
    }
  }
  return open.empty() ? elements : -1;
}

TrajectoryPlot three_series() {
  TrajectoryPlot p;
  p.title = "a < b & c";
  p.names = {"x1", "x2", "x3"};
  for (int k = 0; k <= 200; ++k) {
    const double t = k * 0.05;
    p.t.push_back(t);
    p.x.push_back({std::sin(t), std::cos(t), t});
    p.xh.push_back({std::sin(t) + std::exp(-t), std::cos(t), t - std::exp(-2 * t)});
  }
  return p;
}

TEST(Svg, WellFormedAndDeterministic) {
  const std::string a = render_svg(three_series()), b = render_svg(three_series());
  EXPECT_EQ(a, b);
  EXPECT_GT(balanced_elements(a), 6);
  EXPECT_NE(a.find("<svg"), std::string::npos);
  EXPECT_EQ(a.find("nan"), std::string::npos);
  EXPECT_EQ(a.find("a < b"), std::string::npos);  // the title is escaped
}

TEST(Auto, ChoosesCanonicalForSeed003) {
  std::string why;
  const auto m = resolve_methods(analyse(parse_model(kSeed003, "s.sym")), {"auto"}, why);
  ASSERT_EQ(m, std::vector<std::string>{"canonical"});
  EXPECT_EQ(why.rfind("auto: chose 'canonical' because ", 0), 0u) << why;
}

TEST(Auto, AllGivesCanonicalAndPerfect) {
  std::string why;
  const auto m = resolve_methods(analyse(parse_model(kSeed003, "s.sym")), {"all"}, why);
  EXPECT_EQ(m, (std::vector<std::string>{"canonical", "perfect"}));
}

TEST(Auto, RefusesRayleighNamingEveryDesign) {
  const Analysis a = analyse(parse_model(kRayleigh, "rayleigh.sym"));
  std::string why;
  try {
    resolve_methods(a, {"auto"}, why);
    FAIL() << "auto accepted rayleigh: " << why;
  } catch (const UserError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("canonical: "), std::string::npos) << msg;
    EXPECT_NE(msg.find("perfect: "), std::string::npos) << msg;
    EXPECT_NE(msg.find("not implemented yet: riccati"), std::string::npos) << msg;
  }
}

TEST(Auto, UnknownAndPlannedMethodsDiffer) {
  const Analysis a = analyse(parse_model(kSeed003, "s.sym"));
  std::string why, unknown, planned;
  try {
    resolve_methods(a, {"bogus"}, why);
  } catch (const UserError& e) {
    unknown = e.what();
  }
  try {
    resolve_methods(a, {"riccati"}, why);
  } catch (const UserError& e) {
    planned = e.what();
  }
  EXPECT_NE(unknown.find("unknown method 'bogus'"), std::string::npos) << unknown;
  EXPECT_NE(planned.find("'riccati' is not implemented in this version"), std::string::npos)
      << planned;
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// A file that cannot be written (its name points into a missing sub-directory) after a good
// one: the old content stays, and no staging directory is left behind.
TEST(OutputDir, FailureLeavesOldContentAndNoStaging) {
  const fs::path dir =
      fs::temp_directory_path() / ("obsynth_test_outdir_" + std::to_string(getpid()));
  fs::remove_all(dir);
  write_output_dir(dir.string(), {{"a.hpp", "old a"}, {"b.hpp", "old b"}});
  EXPECT_THROW(write_output_dir(dir.string(), {{"a.hpp", "new a"}, {"no/such/b.hpp", "new b"}}),
               UserError);
  EXPECT_EQ(slurp(dir / "a.hpp"), "old a");
  EXPECT_EQ(slurp(dir / "b.hpp"), "old b");
  size_t entries = 0;
  for (const auto& e : fs::directory_iterator(dir)) ++entries, (void)e;
  EXPECT_EQ(entries, 2u);
  fs::remove_all(dir);
}

}  // namespace
