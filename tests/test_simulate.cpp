// simulate (convergence, first-order ZOH error, divergence detection) and the SVG writer.
// Oracles are written here independently of the code under test (a tiny XML tag matcher).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>

#include <unistd.h>

#include "analysis/analysis.hpp"
#include "app/output_dir.hpp"
#include "app/simulate.hpp"
#include "app/svg_plot.hpp"
#include "app/synthesize.hpp"
#include "app/trial.hpp"
#include "foundation/diagnostics.hpp"
#include "front/bind.hpp"
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

// ---- The plot's structure, read back with a small attribute reader (independent of the
// writer): one panel per state with its own axis, the domain box, the relative error panel.

// The text of the first element group `<g class='cls' ...>` ... `</g>` with data-state = state
// (any state when empty).
std::string group(const std::string& svg, const std::string& cls, const std::string& state = "") {
  const std::string open =
      "<g class='" + cls + "'" + (state.empty() ? "" : " data-state='" + state + "'");
  const size_t a = svg.find(open);
  if (a == std::string::npos) return "";
  return svg.substr(a, svg.find("</g>", a) - a);
}

size_t count(const std::string& s, const std::string& what) {
  size_t c = 0;
  for (size_t p = s.find(what); p != std::string::npos; p = s.find(what, p + 1)) ++c;
  return c;
}

// (data-value, y1) of every element of a class (grid lines, domain lines) in a group.
std::vector<std::pair<double, double>> valued_lines(const std::string& g, const std::string& cls) {
  std::vector<std::pair<double, double>> out;
  const std::regex re("class='" + cls + "' data-value='([^']+)' x1='[^']+' y1='([^']+)'");
  for (auto it = std::sregex_iterator(g.begin(), g.end(), re); it != std::sregex_iterator(); ++it)
    out.emplace_back(std::stod((*it)[1]), std::stod((*it)[2]));
  return out;
}

// The axis value at pixel row y, from the panel's first and last grid lines.
double axis_value(const std::vector<std::pair<double, double>>& grid, double y) {
  const auto& [va, ya] = grid.front();
  const auto& [vb, yb] = grid.back();
  return va + (y - ya) * (vb - va) / (yb - ya);
}

// The points of the polylines of a class, in order.
std::vector<std::vector<std::pair<double, double>>> polylines(const std::string& g,
                                                              const std::string& cls) {
  std::vector<std::vector<std::pair<double, double>>> out;
  const std::regex re("<polyline class='" + cls + "'[^>]* points='([^']*)'");
  for (auto it = std::sregex_iterator(g.begin(), g.end(), re); it != std::sregex_iterator(); ++it) {
    out.emplace_back();
    std::istringstream pts((*it)[1]);
    std::string xy;
    while (pts >> xy)
      out.back().emplace_back(std::stod(xy.substr(0, xy.find(','))),
                              std::stod(xy.substr(xy.find(',') + 1)));
  }
  return out;
}

// The panel's frame rectangle (x, y, width, height): the group's first rect.
std::array<double, 4> frame_of(const std::string& g) {
  std::smatch m;
  const std::regex re("<rect x='([^']+)' y='([^']+)' width='([^']+)' height='([^']+)'");
  EXPECT_TRUE(std::regex_search(g, m, re));
  return {std::stod(m[1]), std::stod(m[2]), std::stod(m[3]), std::stod(m[4])};
}

TrajectoryPlot boxed_series() {
  TrajectoryPlot p = three_series();
  p.boxes = {{-1.5, 1.5, true}, {-2, 2, true}, {-2, 2, false}};
  return p;
}

TEST(Svg, OnePanelPerStateWithItsOwnAxisAndTheDomainBox) {
  const std::string svg = render_svg(boxed_series());
  EXPECT_GT(balanced_elements(svg), 6);
  EXPECT_EQ(count(svg, "<g class='state-panel'"), 3u);
  EXPECT_EQ(count(svg, "<g class='error-panel'"), 1u);
  // x1 = sin t in [-1.5, 1.5]: its own axis stays near that box; x3 = t reaches 10 on its own.
  const auto g1 = valued_lines(group(svg, "state-panel", "x1"), "ygrid");
  const auto g3 = valued_lines(group(svg, "state-panel", "x3"), "ygrid");
  ASSERT_GE(g1.size(), 2u);
  ASSERT_GE(g3.size(), 2u);
  for (const auto& [v, y] : g1) EXPECT_LE(std::abs(v), 2.5) << v;
  EXPECT_GE(g3.back().first, 8);
  // The declared boxes are drawn at their values on their panel's own axis; x3's is not drawn.
  for (const auto& [state, lo, hi] :
       std::vector<std::tuple<std::string, double, double>>{{"x1", -1.5, 1.5}, {"x2", -2, 2}}) {
    const std::string g = group(svg, "state-panel", state);
    const auto marks = valued_lines(g, "domain");
    ASSERT_EQ(marks.size(), 2u) << state;
    EXPECT_EQ(marks[0].first, lo);
    EXPECT_EQ(marks[1].first, hi);
    const auto grid = valued_lines(g, "ygrid");
    for (const auto& [v, y] : marks) EXPECT_NEAR(axis_value(grid, y), v, 0.02) << state;
  }
  EXPECT_EQ(count(group(svg, "state-panel", "x3"), "class='domain"), 0u);
}

// The error panel shows |x_i - xh_i| / (box width of i) on a log axis: read back at t = 0.
TEST(Svg, RelativeErrorPanelIsScaledByTheBoxWidth) {
  const TrajectoryPlot p = boxed_series();
  const std::string g = group(render_svg(p), "error-panel");
  const auto grid = valued_lines(g, "ygrid");
  const auto lines = polylines(g, "error");
  ASSERT_EQ(lines.size(), 3u);
  ASSERT_GE(grid.size(), 2u);
  // x1: |sin 0 - (sin 0 + 1)| / 3; x3: |0 - (0 - 1)| / 4 (the default box's width).
  EXPECT_NEAR(axis_value(grid, lines[0].front().second), std::log10(1.0 / 3), 0.02);
  EXPECT_NEAR(axis_value(grid, lines[2].front().second), std::log10(1.0 / 4), 0.02);
}

// A run whose error grows to 1e250 and then leaves the finite numbers: the log axis keeps the
// small early errors readable (each where it belongs), the curves stay in the panel, the end
// is marked, and nothing non-finite is written.
TEST(Svg, DivergingRunKeepsTheHistoryOnTheLogAxis) {
  TrajectoryPlot p;
  p.names = {"x1"};
  p.boxes = {{-1, 1, true}};
  for (int k = 0; k <= 600; ++k) {
    const double t = k * 0.01, e = 1e-3 * std::pow(10.0, t * 42);  // 1e-3 .. 1e249
    p.t.push_back(t);
    p.x.push_back({0.5});
    p.xh.push_back({0.5 + e});
  }
  p.t.push_back(6.01);
  p.x.push_back({0.5});
  p.xh.push_back({std::nan("")});
  const std::string svg = render_svg(p);
  EXPECT_EQ(balanced_elements(svg) > 0, true);
  EXPECT_EQ(svg.find("nan"), std::string::npos);
  EXPECT_EQ(svg.find("inf"), std::string::npos);
  const std::string g = group(svg, "error-panel");
  const auto grid = valued_lines(g, "ygrid");
  const auto lines = polylines(g, "error");
  ASSERT_EQ(lines.size(), 1u);
  ASSERT_GE(grid.size(), 2u);
  // Every sample up to t = 0.05 at its own height: log10(e / 2) = -3.3 + 42 t.
  for (size_t i = 0; i <= 5; ++i)
    EXPECT_NEAR(axis_value(grid, lines[0][i].second), std::log10(0.5e-3) + 42 * 0.01 * i, 0.05)
        << i;
  const auto [x, y, w, h] = frame_of(g);
  for (const auto& [px, py] : lines[0]) {
    EXPECT_GE(px, x - 0.1);
    EXPECT_LE(px, x + w + 0.1);
    EXPECT_GE(py, y - 0.1);
    EXPECT_LE(py, y + h + 0.1);
  }
  EXPECT_GE(count(g, "class='diverged'"), 1u);
  EXPECT_GE(count(g, "class='clip'"), 1u);  // where the error leaves the top of the axis
}

// simulate's own diverging run (seed 004's input on seed 003's model): its plot's error panel
// starts at |x(0) - xh(0)| / 4 (box [-2, 2]) for both states, not clamped to the axis bottom.
TEST(Simulate, DivergingRunPlotKeepsTheHistory) {
  const auto r = run_seed003(Sampling::continuous, 1e-3, "20 - 2*sqrt((t-5)^2)");
  ASSERT_FALSE(r.diverged.empty());
  const std::string g = group(r.svg, "error-panel");
  const auto grid = valued_lines(g, "ygrid");
  const auto lines = polylines(g, "error");
  ASSERT_EQ(lines.size(), 2u);
  ASSERT_GE(grid.size(), 2u);
  for (const auto& line : lines)
    EXPECT_NEAR(axis_value(grid, line.front().second), std::log10(0.5 / 4), 0.02);
  EXPECT_GE(count(g, "class='diverged'"), 1u);
}

// ---- auto names the design it ran.
TEST(Simulate, AutoNamesTheDesignItRan) {
  SimulationOptions o;
  o.method = "auto";
  o.u_text = "sin(t)";
  o.x0 = {0.5, -0.5};
  o.xhat0 = {0, 0};
  o.t_end = 1;
  o.dt = 1e-2;
  const auto r = simulate(analyse(parse_model(kSeed003, "seed003.sym")), o);
  EXPECT_NE(r.method, "auto");
  EXPECT_FALSE(r.method.empty());
  EXPECT_NE(r.explanation.find("chose '" + r.method + "'"), std::string::npos) << r.explanation;
  EXPECT_NE(r.summary.find("observer: " + r.method), std::string::npos) << r.summary;
  EXPECT_NE(r.svg.find(": " + r.method + " observer (chosen by auto)"), std::string::npos);
}

// ---- --plant-param. x' = -k x, y = x: the canonical observer (design.md section 1, n = 1:
// T = x, l = -k y) is xh' = -k_o y + K (y - xh), K = 4 for the pole -4. With the plant's k_p,
// x = x0 e^{-k_p t} and xh = B (e^{-k_p t} - e^{-K t}) for xh(0) = 0, B = (K - k_o) x0 / (K -
// k_p): the plant runs with k_p, the observer with its own k_o.
const char* kDecay = R"(model decay
states x1
params k, c = 3
f = [ -k*x1 ]
h = [ x1 ]
domain x1 in [-2, 2], k in [1/2, 3/2]
)";

SimulationOptions decay_options(std::vector<std::string> plant_params) {
  SimulationOptions o;
  o.method = "canonical";
  o.design.values["poles"] = "-4";
  o.x0 = {1};
  o.xhat0 = {0};
  o.t_end = 2;
  o.dt = 1e-3;
  o.plant_params = std::move(plant_params);
  return o;
}

void expect_decay(const SimulationResult& r, double kp, double ko) {
  ASSERT_TRUE(r.diverged.empty()) << r.diverged;
  const double K = 4, B = (K - ko) / (K - kp);
  for (size_t i = 0; i < r.t.size(); i += 250) {
    const double t = r.t[i];
    EXPECT_NEAR(r.x[i][0], std::exp(-kp * t), 1e-8) << t;
    EXPECT_NEAR(r.xh[i][0], B * (std::exp(-kp * t) - std::exp(-K * t)), 1e-8) << t;
  }
}

TEST(Simulate, PlantParamChangesThePlantNotTheObserver) {
  const Model m = parse_model(kDecay, "decay.sym");
  const Analysis a = analyse(m);
  expect_decay(simulate(a, decay_options({})), 1, 1);  // both at the box centre
  const auto r = simulate(a, decay_options({"k=2"}));
  expect_decay(r, 2, 1);
  EXPECT_NE(r.summary.find("k = 2 (observer: 1"), std::string::npos) << r.summary;
  EXPECT_NE(r.svg.find("k = 2 (observer: 1"), std::string::npos);
}

// --param binds the observer's k; --plant-param still sets the plant's (the model as read).
TEST(Simulate, PlantParamOverridesAParamBinding) {
  const Model unbound = parse_model(kDecay, "decay.sym");
  const Analysis a = analyse(bind_parameters(unbound, {"k=5/4"}));
  auto o = decay_options({"k=2"});
  o.unbound_model = &unbound;
  expect_decay(simulate(a, o), 2, 1.25);
  o.plant_params.clear();
  expect_decay(simulate(a, o), 1.25, 1.25);
}

TEST(Simulate, PlantParamErrors) {
  const Analysis a = analyse(parse_model(kDecay, "decay.sym"));
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"nope=1"},
       "--plant-param nope: the model has no parameter 'nope' (its free parameters: k)"},
      {{"c=1"},
       "--plant-param c: 'c' is not a free parameter (the model file gives it the value 3)"},
      {{"k=abc"}, "--plant-param k=abc"},
      {{"k"}, "--plant-param 'k': expected name=value"},
      {{"k=1", "k=2"}, "--plant-param k: given twice"},
  };
  for (const auto& [params, message] : cases) {
    try {
      simulate(a, decay_options(params));
      ADD_FAILURE() << "no error for " << params.front();
    } catch (const UserError& e) {
      EXPECT_NE(std::string(e.what()).find(message), std::string::npos) << e.what();
    }
  }
}

// auto's closed-loop trial (app/trial.hpp): the canonical observer of seed 003's example
// converges from 20 % errors (its error decays at the poles' rate; over 300 time constants it is
// at rounding level), and the trial says so; the same observer with its right-hand side negated
// (poles mirrored into the right half plane, unstable by construction) leaves the box, and the
// trial fails it. Both are deterministic.
TEST(Trial, PassesAConvergingObserverAndFailsAnUnstableOne) {
  const Analysis a = analyse(parse_model(kSeed003, "slawinski17.sym"));
  const ObserverSpec good = build_design(a, "canonical", DesignOptions{});
  const TrialOutcome pass = closed_loop_trial(a, good);
  EXPECT_EQ(pass.verdict, TrialVerdict::passed) << pass.setup << ": " << pass.text;
  EXPECT_NE(pass.setup.find("sampled"), std::string::npos) << pass.setup;
  EXPECT_EQ(closed_loop_trial(a, good).text, pass.text);
  ObserverSpec bad = good;  // w' = -(A_cl w + c): the poles mirrored
  bool negated = false;
  for (auto& f : bad.functions)
    if (f.name == bad.roles.rhs) {
      for (auto& e : f.outputs) e = -e;
      negated = true;
    }
  ASSERT_TRUE(negated);
  const TrialOutcome fail = closed_loop_trial(a, bad);
  EXPECT_EQ(fail.verdict, TrialVerdict::failed) << fail.text;
  EXPECT_FALSE(fail.text.empty());
}

// auto states the trial of what it chose, and never takes a design whose trial failed while
// another passes (the engineering models' default_path_fast test has the designs it passes
// over: high-gain on predator_prey and bioreactor).
TEST(Trial, AutoStatesTheTrialOfItsChoice) {
  const Analysis a = analyse(parse_model(kSeed003, "slawinski17.sym"));
  std::string explanation;
  const BuiltDesign chosen = choose_and_build(a, "auto", DesignOptions{}, explanation);
  EXPECT_NE(explanation.find("closed-loop trial"), std::string::npos) << explanation;
  const TrialOutcome t = closed_loop_trial(a, chosen.spec);
  EXPECT_NE(t.verdict, TrialVerdict::failed) << t.text;
}

}  // namespace

namespace {

// The two-link arm (both angles measured) with riccati's default tuning, simulated in continuous
// time at a --dt far past the observer's largest safe RK4 step: the run takes the sub-steps the
// firmware step takes (ObserverSpec::max_substep), so it converges, and at the common sample
// times it agrees with a run whose --dt is already below the safe step.
SimulationResult run_arm(double dt) {
  SimulationOptions o;
  o.method = "riccati";
  o.u_text = "2*sin(t), 0.5*cos(t)";
  o.x0 = {0.3, -0.2, 0, 0};
  o.xhat0 = {0.6, 0.3, 0.8, -0.8};
  o.t_end = 2;
  o.dt = dt;
  return simulate(analyse(load_model(std::string(OBSYNTH_SOURCE_DIR) + "/models/two_link_arm.sym")),
                  o);
}

}  // namespace

TEST(Simulate, ContinuousRunTakesTheObserversSubSteps) {
  const ObserverSpec s = build_design(
      analyse(load_model(std::string(OBSYNTH_SOURCE_DIR) + "/models/two_link_arm.sym")), "riccati",
      {});
  ASSERT_GT(s.max_substep, 0);
  const double safe = s.max_substep.to_double();
  const double coarse = 0.02;
  ASSERT_GT(coarse, 4 * safe) << "the test needs a --dt well past the safe step";
  const auto a = run_arm(coarse), b = run_arm(coarse / 40);
  ASSERT_TRUE(a.diverged.empty()) << a.diverged;
  ASSERT_TRUE(b.diverged.empty()) << b.diverged;
  EXPECT_LT(final_error(a), 1e-3);
  // t = 0.5: sample 25 of the coarse run, 1000 of the fine one.
  for (std::size_t i = 0; i < 4; ++i) EXPECT_NEAR(a.xh[25][i], b.xh[1000][i], 1e-3) << i;
}
