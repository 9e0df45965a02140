// simulate (convergence, first-order ZOH error, divergence detection) and the SVG writer.
// Oracles are written here independently of the code under test (a tiny XML tag matcher).
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

}  // namespace
