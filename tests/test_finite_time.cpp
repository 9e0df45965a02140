// The finite-time epsilon-T observer (seed 004, Garcia & Hernandez): example (14) with the
// paper's parameters through `obsynth simulate`'s machinery, and the generated C++ (float,
// double) and C99 code against the simulator's evaluation of the same tables.
//
// Seed 004 transcription problems met here (see also models/garcia14.sym):
//  - (15) prints the weights as 1/(eps + |q_k(x_i) - xi|), power 1, where (13) has power n + 2.
//    With power 1 on a 161 x 161 grid the far field dominates (sum of 1/d over a 2-D grid
//    diverges with the grid size): measured here, the estimate collapses towards the centre of
//    G and the error stays ~0.8, so "|Q_k(q_k(x_i)) - x_i| < 2e-3" cannot hold for (15) as
//    printed. The test uses (13)'s power n + 2 = 4 (--weight-power 4).
//  - eps = 0.05 and the grid norm 0.0125 only compare if q is measured in state units; with
//    b = 1 and the listed (mostly slow) eigenvalues, q varies ~50x less along the phase of the
//    oscillation than along its radius, so the design whitens q and scales it by its median
//    sensitivity (report row "kernel metric").
//  - "eps = 0." lost its digits: the accuracy asserted below is the design's own sampled bound.
//  - The paper switches the inverse Q_k with the sampled input and reports peaks up to 0.2 at
//    the switches. Switching to the level nearest the input's window mean, with mu = 1 and the
//    ramp moving u by 1 per window, gives peaks of 0.29 here (the window's mean sits half a
//    level from both tables at a switch). The design's default rule (window-interpolate, see
//    finite_time.cpp choose_kernel) interpolates q_nu between the two neighbouring levels'
//    tables at the window mean (eq. 6, 15; the paper's "refining the control mesh" without more
//    tables): measured max error 0.116 after 0.55 s, no peaks.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <array>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "analysis/analysis.hpp"
#include "app/simulate.hpp"
#include "app/synthesize.hpp"
#include "designs/registry.hpp"
#include "emit/emit_c.hpp"
#include "emit/emit_cxx.hpp"
#include "foundation/diagnostics.hpp"
#include "front/parse.hpp"
#include "support/shell.hpp"

using namespace obsynth;
namespace fs = std::filesystem;

namespace {

const std::string kModel = std::string(OBSYNTH_SOURCE_DIR) + "/models/garcia14.sym";

Analysis garcia14() {
  std::ifstream in(kModel);
  std::stringstream text;
  text << in.rdbuf();
  return analyse(parse_model(text.str(), "models/garcia14.sym"));
}

DesignOptions paper_options(const std::string& grid, const std::string& dt) {
  DesignOptions o;
  o.values = {
      {"window", "0.5"},          {"filter-poles", "-0.01,-0.05,-0.1,-0.5,-1,-1.5,-2,-4,-8,-16"},
      {"grid-step", grid},        {"input-step", "1"},
      {"kernel-epsilon", "0.05"}, {"weight-power", "4"},
      {"sample-period", dt}};
  return o;
}

// u(t) = 20 - 2|t - 5|: 10 -> 20 -> 10 over 10 s, and its exact integral (the plant is a
// rotation by theta(t) = int_0^t u: x1 = cos theta, x2 = -sin theta from x(0) = (1, 0)).
double ramp(double t) {
  return 20 - 2 * std::fabs(t - 5);
}
double theta(double t) {
  if (t <= 5) return 10 * t + t * t;
  const double s = t - 5;
  return 75 + 20 * s - s * s;
}

double report_number(const ObserverSpec& s, const std::string& key) {
  for (const auto& r : s.report)
    if (r.key == key) return std::stod(r.value);
  ADD_FAILURE() << "no report row " << key;
  return 0;
}

TEST(FiniteTime, AppliesToTheNonSmoothRectifierModel) {
  const Analysis a = garcia14();
  const Design* d = find_design("finite-time");
  ASSERT_NE(d, nullptr);
  const Verdict v = d->applies(a);
  EXPECT_TRUE(v.applies) << v.text();
  // The Lie-algebraic designs do not apply, and say why (no crash on sqrt(x1^2)).
  EXPECT_FALSE(find_design("canonical")->applies(a).applies);
  // Chosen by name only (it builds tables): neither --method all nor auto picks it (riccati,
  // which applies under inputs, may).
  std::string why;
  const auto all = resolve_methods(a, {"all"}, why);
  EXPECT_EQ(std::find(all.begin(), all.end(), "finite-time"), all.end());
  const auto chosen = resolve_methods(a, {"auto"}, why);
  EXPECT_NE(chosen.front(), "finite-time");
}

TEST(FiniteTime, OptionDiagnostics) {
  const Analysis a = garcia14();
  auto build = [&](std::map<std::string, std::string> v) {
    DesignOptions o = paper_options("0.25", "0.01");
    for (auto& [k, x] : v) o.values[k] = x;
    return build_design(a, "finite-time", o);
  };
  EXPECT_THROW(build({{"sample-period", "0.3"}}), UserError);  // T not a multiple
  EXPECT_THROW(build({{"grid-step", "0.3"}}), UserError);      // does not divide [-1, 1]
  EXPECT_THROW(build({{"filter-poles", "-1,2"}}), UserError);
  EXPECT_THROW(build({{"filter-poles", "-1,-1"}}), UserError);
  EXPECT_THROW(build({{"weight-power", "0"}}), UserError);
  EXPECT_THROW(build({{"input-rate", "-1"}}), UserError);
  EXPECT_THROW(build({{"level-rule", "window-linear"}}), UserError);
  // A model without a domain box for its states does not qualify.
  const Model m = parse_model("model nobox\nstates x\nf = [ -x ]\nh = [ x ]\n", "nobox.sym");
  const Verdict v = find_design("finite-time")->applies(analyse(m));
  EXPECT_FALSE(v.applies);
  EXPECT_NE(v.text().find("domain"), std::string::npos) << v.text();
}

// Seed 004, example (14), with the paper's parameters: T = 0.5, the ten listed eigenvalues,
// grid 0.0125 over [-1, 1]^2 (161 x 161 points), input levels 10, 11, ..., 20 (mu = 1),
// eps = 0.05, x(0) = (1, 0), u ramping 10 -> 20 -> 10 over 10 s. The sampled bound is asked to
// cover input ramps of slope 2 (--input-rate: this ramp's), as u moves over every window.
TEST(FiniteTime, Seed004Example14) {
#ifdef OBSYNTH_SANITIZED
  // 161 x 161 x 11 backward simulations: 16 s in Release, over 5 minutes under ASan + UBSan.
  // The same code runs under the sanitizers on the coarse grid (GeneratedCodeMatchesSimulator).
  GTEST_SKIP() << "the paper-size tables run in the Release pass";
#endif
  const Analysis a = garcia14();
  DesignOptions design = paper_options("0.0125", "0.001");
  design.values["input-rate"] = "2";
  const ObserverSpec spec = build_design(a, "finite-time", design);
  ASSERT_EQ(spec.update, UpdateKind::sampled_delay);
  ASSERT_TRUE(spec.sampled_delay.has_value());
  EXPECT_EQ(spec.sampled_delay->points(), 161u * 161u);
  EXPECT_EQ(spec.sampled_delay->levels, 11u);
  EXPECT_EQ(spec.sampled_delay->delay_steps, 500u);
  EXPECT_EQ(spec.table("observation_map")->size(), 11u * 161u * 161u * 10u);
  EXPECT_TRUE(spec.sampled_delay->level_interpolate);  // the default level rule
  EXPECT_TRUE(spec.sampled_delay->level_window_mean);
  const double bound = report_number(spec, "error bound (sampled)");
  EXPECT_GT(bound, 0.05);
  EXPECT_LT(bound, 0.2);

  SimulationOptions o;
  o.method = "finite-time";
  o.design = design;
  o.u_text = "20 - 2*sqrt((t-5)^2)";
  o.x0 = {1, 0};
  o.xhat0 = {0, 0};
  o.t_end = 10;
  o.dt = 1e-3;
  const SimulationResult r = simulate(a, o);
  ASSERT_TRUE(r.diverged.empty()) << r.diverged;
  ASSERT_EQ(r.t.size(), 10001u);

  // A switching rule changes the level where the input's window mean crosses u_k + 1/2 (nearest)
  // or u_k (the paper's floor on u(t_i), t_i on a mesh of norm T): on this ramp both happen
  // every 0.5 s. Computed here from u alone; the peaks, if any, are there.
  std::vector<double> switches;
  for (int k = 1; k <= 20; ++k) switches.push_back(0.5 * k);
  auto near_switch = [&](double t, double w) {
    for (double s : switches)
      if (std::fabs(t - s) <= w) return true;
    return false;
  };
  std::vector<double> peak(switches.size(), 0.0);  // max error within 0.1 s of each switch
  double max_after = 0, max_away = 0, max_plant = 0, max_e1 = 0, max_e2 = 0;
  for (std::size_t k = 0; k < r.t.size(); ++k) {
    const double t = r.t[k];
    // The simulator's plant against the exact rotation (an independent oracle).
    max_plant = std::max(
        max_plant, std::hypot(r.x[k][0] - std::cos(theta(t)), r.x[k][1] + std::sin(theta(t))));
    const double e = std::hypot(r.x[k][0] - r.xh[k][0], r.x[k][1] - r.xh[k][1]);
    if (t < 0.5 - 1e-9) {
      // The window is not full yet: the estimate stays the reset value.
      EXPECT_EQ(r.xh[k][0], 0.0);
      EXPECT_EQ(r.xh[k][1], 0.0);
      continue;
    }
    if (t < 0.55) continue;
    max_after = std::max(max_after, e);
    max_e1 = std::max(max_e1, std::fabs(r.x[k][0] - r.xh[k][0]));
    max_e2 = std::max(max_e2, std::fabs(r.x[k][1] - r.xh[k][1]));
    if (!near_switch(t, 0.1)) max_away = std::max(max_away, e);
    for (std::size_t s = 0; s < switches.size(); ++s)
      if (std::fabs(t - switches[s]) <= 0.1) peak[s] = std::max(peak[s], e);
  }
  EXPECT_LT(max_plant, 1e-6);
  // Enters the reported bound by about T = 0.5 s and stays in it, at the switches too.
  EXPECT_LE(max_after, bound);
  // The paper's figures: within the specification from about t = 0.5 on, peaks at the input
  // switches bounded by 0.2 (measured here: 0.116 after 0.55 s, 0.115 away from the switches).
  EXPECT_LT(max_away, 0.2);
  EXPECT_LE(max_after, 0.2);
  std::string peaks;
  for (std::size_t s = 0; s < switches.size(); ++s) {
    EXPECT_LE(peak[s], 0.2) << "at the switch t = " << switches[s];
    peaks += fmt::format("{}{:.3f}", s ? " " : "", peak[s]);
  }
  std::printf(
      "seed 004 (14): max |x - xh| after 0.55 s %.4f (|e1| %.4f, |e2| %.4f), away from "
      "the switches %.4f, sampled bound %.4f\n  peaks at t = 0.5, 1, ..., 10: %s\n",
      max_after, max_e1, max_e2, max_away, bound, peaks.c_str());
  RecordProperty("max_error_after_0_55", std::to_string(max_after));
  RecordProperty("max_error_away_from_switches", std::to_string(max_away));
  RecordProperty("peaks_at_switches", peaks);
  RecordProperty("sampled_bound", std::to_string(bound));
}

// ---- generated code against the simulator --------------------------------------------------

std::string run(const std::string& cmd) {
  return obsynth::testing::run_command(cmd);
}

// Drivers of a two-state finite-time observer, fed the simulator's CSV (t, x1, x2, ...): the
// model's names come as macros (cxx_defines / c_defines below). The last step, at twice the
// sample period, must be refused.
const char* kCxxDriver = R"(#include <cstdio>
#include <cmath>
#include HEADER
using Obs = obsynth_gen::NS::CLASS<SCALAR>;
int main(int argc, char** argv) {
  (void)argc;
  static Obs obs;  // the delay line is fixed storage inside the object
  std::FILE* f = std::fopen(argv[1], "r");
  char line[512];
  if (!std::fgets(line, sizeof line, f)) return 2;
  double t, x1, x2, a, b;
  while (std::fscanf(f, "%lf,%lf,%lf,%lf,%lf", &t, &x1, &x2, &a, &b) == 5) {
    Obs::State x;
    x << SCALAR(x1), SCALAR(x2);
    Obs::Output y;
    obsynth_gen::NS::FiniteTimeFunctions<SCALAR>::h(x, y);
    Obs::Input u;
    u(0) = SCALAR(U0(t));
    if (obs.step(SCALAR(0.01), u, y) != obsynth::Status::ok) return 3;
    std::printf("%.17g,%.17g\n", double(obs.estimate()(0)), double(obs.estimate()(1)));
  }
  return obs.step(SCALAR(0.02), Obs::Input::Zero(), Obs::Output::Zero()) == obsynth::Status::ok;
}
)";

const char* kCDriver = R"(#include <stdio.h>
#include <math.h>
#include HEADER
#define CAT2(a, b) a##b
#define CAT(a, b) CAT2(a, b)
#define F(x) CAT(PREFIX, x)
static F(observer) obs;
int main(int argc, char** argv) {
  char line[512];
  double t, x1, x2, a, b;
  FILE* f = fopen(argv[1], "r");
  (void)argc;
  F(init)(&obs);
  if (!fgets(line, sizeof line, f)) return 2;
  while (fscanf(f, "%lf,%lf,%lf,%lf,%lf", &t, &x1, &x2, &a, &b) == 5) {
    F(scalar) x[2], y[OUTPUTS], u[1];
    x[0] = (F(scalar))x1;
    x[1] = (F(scalar))x2;
    F(h)(x, y);
    u[0] = (F(scalar))(U0(t));
    if (F(step)(&obs, (F(scalar))0.01, u, y) != F(ok)) return 3;
    printf("%.17g,%.17g\n", (double)obs.xh[0], (double)obs.xh[1]);
  }
  return 0;
}
)";

// The driver macros for a model: namespace and class (C++), function prefix and outputs (C),
// and the input u(t) both plants take.
std::string cxx_defines(const std::string& ns, const std::string& cls, const std::string& u) {
  return "#define NS " + ns + "\n#define CLASS " + cls + "\n#define U0(t) (" + u + ")\n";
}
std::string c_defines(const std::string& prefix, int outputs, const std::string& u) {
  return "#define PREFIX " + prefix + "\n#define OUTPUTS " + std::to_string(outputs) +
         "\n#define U0(t) (" + u + ")\n";
}
const char* kGarciaInput = "20 - 2 * sqrt((t - 5) * (t - 5))";

std::vector<std::array<double, 2>> read_pairs(const std::string& text) {
  std::vector<std::array<double, 2>> v;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    std::array<double, 2> p{};
    if (std::sscanf(line.c_str(), "%lf,%lf", &p[0], &p[1]) == 2) v.push_back(p);
  }
  return v;
}

// A coarse variant (grid 0.125, 17 x 17 points; dt = 0.01, D = 50) small enough for a
// microcontroller: the generated C++ (double, float) and C99 (double, float) steps against the
// simulator's evaluation of the same tables, fed the simulator's own plant samples.
// rule: the design's --level-rule; all_cases: float and C too (else C++ and C in double).
void generated_matches_simulator(const std::string& rule, bool all_cases) {
  const Analysis a = garcia14();
  DesignOptions d = paper_options("0.125", "0.01");
  d.values["kernel-epsilon"] = "0.3";
  d.values["level-rule"] = rule;
  SimulationOptions o;
  o.method = "finite-time";
  o.design = d;
  o.u_text = "20 - 2*sqrt((t-5)^2)";
  o.x0 = {1, 0};
  o.xhat0 = {0, 0};
  o.t_end = 10;
  o.dt = 0.01;
  const SimulationResult r = simulate(a, o);
  ASSERT_TRUE(r.diverged.empty()) << r.diverged;
  const fs::path dir =
      fs::temp_directory_path() / ("obsynth_ft_" + rule + "_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  { std::ofstream(dir / "sim.csv") << r.csv; }
  const ObserverSpec spec = build_design(a, "finite-time", d);
  const std::string flags =
      "-Wall -Wextra -Werror -Wconversion -Wdouble-promotion -pedantic -O2 -fno-math-errno";
  const std::string inc = fmt::format("-I{0}/runtime -I/usr/include/eigen3", OBSYNTH_SOURCE_DIR);
  struct Case {
    std::string name;
    Precision p;
    bool c;
    double tol;
  };
  for (const Case& k : {Case{"cxx_double", Precision::double_precision, false, 1e-9},
                        Case{"cxx_float", Precision::single, false, 5e-3},
                        Case{"c_double", Precision::double_precision, true, 1e-9},
                        Case{"c_float", Precision::single, true, 5e-3}}) {
    if (!all_cases && k.p == Precision::single) continue;
    SCOPED_TRACE(rule + " " + k.name);
    EmitOptions eo;
    eo.precision = k.p;
    eo.source_name = "models/garcia14.sym";
    const fs::path sub = dir / k.name;
    fs::create_directories(sub);
    std::string build;
    if (!k.c) {
      const EmittedHeader h = emit_cxx_header(a, spec, eo);
      std::ofstream(sub / h.filename) << h.text;
      std::ofstream(sub / "driver.cpp")
          << cxx_defines("garcia14", "Garcia14FiniteTime", "20 - 2 * std::sqrt((t - 5) * (t - 5))")
          << kCxxDriver;
      // Every observer class compiles in float and double whatever the literal precision.
      for (const char* scalar : {"float", "double"}) {
        const std::string out = run(fmt::format(
            "c++ -std=c++17 {} -fno-exceptions -fno-rtti -DEIGEN_NO_MALLOC {} "
            "-DHEADER='\"{}\"' -DSCALAR={} {} -o {}",
            flags, inc, (sub / h.filename).string(), scalar, (sub / "driver.cpp").string(),
            (sub / (std::string("drv_") + scalar)).string()));
        ASSERT_EQ(out.find("FAILED"), std::string::npos) << out;
      }
      build = (sub / (k.p == Precision::single ? "drv_float" : "drv_double")).string();
    } else {
      const EmittedHeader h = emit_c_pair(a, spec, eo);
      std::ofstream(sub / h.filename) << h.text;
      std::ofstream(sub / h.source_filename) << h.source_text;
      std::ofstream(sub / "driver.c")
          << c_defines("garcia14_finite_time_", 1, kGarciaInput) << kCDriver;
      const std::string out = run(fmt::format(
          "cc -std=c99 {} -I{} -I{}/runtime -DHEADER='\"{}\"' {} {} -lm -o {}", flags, sub.string(),
          OBSYNTH_SOURCE_DIR, h.filename, (sub / h.source_filename).string(),
          (sub / "driver.c").string(), (sub / "drv").string()));
      ASSERT_EQ(out.find("FAILED"), std::string::npos) << out;
      build = (sub / "drv").string();
    }
    const std::string out = run(build + " " + (dir / "sim.csv").string());
    const auto got = read_pairs(out);
    ASSERT_EQ(out.find("FAILED"), std::string::npos) << out.substr(out.size() - 400);
    ASSERT_EQ(got.size(), r.t.size()) << out.substr(0, 400);  // one step per CSV row
    double worst = 0;
    std::vector<double> diffs;
    for (std::size_t i = 0; i + 1 < got.size(); ++i) {
      double e = 0;
      for (int s = 0; s < 2; ++s)
        e = std::max(e, std::fabs(got[i][s] - r.xh[i + 1][static_cast<std::size_t>(s)]));
      worst = std::max(worst, e);
      diffs.push_back(e);
    }
    std::sort(diffs.begin(), diffs.end());
    const double p99 = diffs[diffs.size() * 99 / 100];
    std::printf("%s %s: 99th percentile %.3g\n", rule.c_str(), k.name.c_str(), p99);
    EXPECT_LE(worst, k.tol);
    ::testing::Test::RecordProperty(rule + "_" + k.name + "_max_difference", std::to_string(worst));
    std::printf("%s %s: max |xh - xh_simulator| = %.3g\n", rule.c_str(), k.name.c_str(), worst);
  }
  fs::remove_all(dir);
}

// The default rule (the table interpolated between input levels) in C++ and C, float and double.
TEST(FiniteTime, GeneratedCodeMatchesSimulator) {
  generated_matches_simulator("window-interpolate", true);
}

// A switching rule (one level's table per step) still emits and matches, in double.
TEST(FiniteTime, GeneratedSwitchingRuleMatchesSimulator) {
  generated_matches_simulator("window-nearest", false);
}

// The interpolating rule against the switching one, coarse grid and coarse input levels (10, 15,
// 20: the level mismatch dominates the kernel's error), u constant: at a level (u = 15,
// interpolation weight exactly 0) both use table 15 alone and agree bit for bit; half way
// between two levels (u = 12.5) the interpolated table is closer to q_12.5 than either
// neighbour's, and the estimate is better (measured 0.36 against 0.58).
TEST(FiniteTime, InterpolationBetweenInputLevels) {
  const Analysis a = garcia14();
  auto run_rule = [&](const std::string& rule, const std::string& u) {
    SimulationOptions o;
    o.method = "finite-time";
    o.design = paper_options("0.125", "0.01");
    o.design.values["kernel-epsilon"] = "0.3";
    o.design.values["level-rule"] = rule;
    o.design.values["input-step"] = "5";
    o.u_text = u;
    o.x0 = {0.8, 0};
    o.xhat0 = {0, 0};
    o.t_end = 3;
    o.dt = 0.01;
    return simulate(a, o);
  };
  auto max_error = [](const SimulationResult& r) {
    double m = 0;
    for (std::size_t k = 0; k < r.t.size(); ++k)
      if (r.t[k] >= 0.55)
        m = std::max(m, std::hypot(r.x[k][0] - r.xh[k][0], r.x[k][1] - r.xh[k][1]));
    return m;
  };
  const SimulationResult i15 = run_rule("window-interpolate", "15"),
                         n15 = run_rule("window-nearest", "15");
  ASSERT_EQ(i15.xh.size(), n15.xh.size());
  for (std::size_t k = 0; k < i15.xh.size(); ++k) {
    EXPECT_EQ(i15.xh[k][0], n15.xh[k][0]);
    EXPECT_EQ(i15.xh[k][1], n15.xh[k][1]);
  }
  const double ei = max_error(run_rule("window-interpolate", "12.5")),
               en = max_error(run_rule("window-nearest", "12.5"));
  std::printf("u = 12.5: max error interpolated %.4f, nearest level %.4f\n", ei, en);
  EXPECT_LT(ei, 0.75 * en);
}

// ---- defaults: the search for an error target within a memory budget (issue 17) -------------

// Seed 004's example with the defaults, as `obsynth simulate models/garcia14.sym --method
// finite-time --u "20 - 2*sqrt((t-5)^2)" --x0 1,0 --xhat0 0,0 --t-end 10 --dt 1e-3` runs it. The
// plant is checked against the exact rotation (independent oracle). Before the search (window 1,
// weight power 1, epsilon 4 grid steps) the error stayed 0.6-1.0 for the whole run.
SimulationResult judged_run(const Analysis& a) {
  SimulationOptions o;
  o.method = "finite-time";
  o.u_text = "20 - 2*sqrt((t-5)^2)";
  o.x0 = {1, 0};
  o.xhat0 = {0, 0};
  o.t_end = 10;
  o.dt = 1e-3;
  return simulate(a, o);
}

// Largest |x - xh| (Euclidean) over t >= from.
double max_error_after(const SimulationResult& r, double from) {
  double m = 0;
  for (std::size_t k = 0; k < r.t.size(); ++k)
    if (r.t[k] >= from - 1e-9)
      m = std::max(m, std::hypot(r.x[k][0] - r.xh[k][0], r.x[k][1] - r.xh[k][1]));
  return m;
}

TEST(FiniteTime, DefaultsConvergeOnSeed004Example) {
  const Analysis a = garcia14();
  const SimulationResult r = judged_run(a);
  ASSERT_TRUE(r.diverged.empty()) << r.diverged;
  double plant = 0;
  for (std::size_t k = 0; k < r.t.size(); ++k)
    plant = std::max(plant, std::hypot(r.x[k][0] - std::cos(theta(r.t[k])),
                                       r.x[k][1] + std::sin(theta(r.t[k]))));
  EXPECT_LT(plant, 1e-6);
  const double after = max_error_after(r, 0.6), last = max_error_after(r, 9);
  std::printf("defaults: max |x - xh| after 0.6 s %.4f, in the last second %.4f\n", after, last);
  EXPECT_LE(after, 0.2);
  EXPECT_LE(last, 0.1);  // the target: 5 % of the box width 2
}

// The issue's stricter figure for the last second (<= 0.05, Euclidean). The input ramps at 2 / s;
// frozen at its window mean, the phase of the backward trajectory is off by up to rate T^2 / 8
// (0.048 rad at T = 0.437): 0.073 before the slope correction. With it (the slope fitted over
// the window times the tabulated dq/du', first order in the slope) measured 0.0493 after 9 s and
// 0.058 after 0.6 s.
TEST(FiniteTime, DefaultsMeetFivePercentOfTheHalfWidthInTheLastSecond) {
  const SimulationResult r = judged_run(garcia14());
  EXPECT_LE(max_error_after(r, 9), 0.05);
}

// Without the slope correction (--input-slope ignore) the same run misses that figure: the
// correction, not a table setting, closes it.
TEST(FiniteTime, SlopeCorrectionIsWhatMeetsTheLastSecondFigure) {
  const Analysis a = garcia14();
  SimulationOptions o;
  o.method = "finite-time";
  o.design.values = {{"input-slope", "ignore"}};
  o.u_text = "20 - 2*sqrt((t-5)^2)";
  o.x0 = {1, 0};
  o.xhat0 = {0, 0};
  o.t_end = 10;
  o.dt = 1e-3;
  const SimulationResult r = simulate(a, o);
  EXPECT_GT(max_error_after(r, 9), 0.06);
}

// The design's own report for the defaults (the main job without options): target, budget and
// guarantee lines; the verdict carries the guarantee once its plan has built the default tables
// (before, and on another plan, it says they are not built, and claims nothing).
TEST(FiniteTime, DefaultsMeetTheTargetWithinTheBudget) {
  const Analysis a = garcia14();
  const Design* d = find_design("finite-time");
  PlanSet plans(a, DesignOptions{});  // the verdict reads the tables its own plan built
  EXPECT_EQ(plans.verdict(*d).guarantee, Guarantee::none);  // not built yet
  const ObserverSpec s = build_design(plans, "finite-time");
  EXPECT_LE(s.table("observation_map")->size() * 4, 256u * 1024u);
  const Verdict v = plans.verdict(*d);
  EXPECT_EQ(v.guarantee, Guarantee::partial) << v.guarantee_text;
  EXPECT_NE(v.guarantee_text.find("sampled"), std::string::npos) << v.guarantee_text;
  bool met = false;
  for (const auto& row : s.report)
    if (row.key == "error target") met = row.value.find(": met") != std::string::npos;
  EXPECT_TRUE(met);
  const Model other = parse_model(
      "model unbuilt\nstates x\nf = [ -x ]\nh = [ x ]\ndomain x in [-1, 1]\n", "unbuilt.sym");
  const Verdict u = d->applies(analyse(other));
  EXPECT_TRUE(u.applies);
  EXPECT_EQ(u.guarantee, Guarantee::none) << u.guarantee_text;
}

// An impossible target says so: guarantee none, "NOT met" in the report, the summary and the
// header's banner; a budget too small for any grid is an error that names the option.
TEST(FiniteTime, ImpossibleTargetIsReported) {
  const Analysis a = garcia14();
  DesignOptions o;
  o.values = {{"sample-period", "0.01"}, {"error-target", "0.0001"}, {"table-memory", "32"}};
  const ObserverSpec s = build_design(a, "finite-time", o);
  std::string rows;
  for (const auto& row : s.report) rows += row.key + ": " + row.value + "\n";
  EXPECT_NE(rows.find("guarantee: none"), std::string::npos) << rows;
  EXPECT_NE(rows.find("NOT met"), std::string::npos) << rows;
  EXPECT_NE(s.summary.find("NOT met"), std::string::npos) << s.summary;
  std::string banner;
  for (const auto& line : s.description) banner += line + "\n";
  EXPECT_NE(banner.find("WARNING"), std::string::npos) << banner;
  EXPECT_LE(s.table("observation_map")->size() * 4, 32u * 1024u);
  o.values["table-memory"] = "0.1";
  EXPECT_THROW(build_design(a, "finite-time", o), UserError);
}

// The search is deterministic: the same tables and report twice.
TEST(FiniteTime, SearchIsDeterministic) {
  const Analysis a = garcia14();
  DesignOptions o;
  o.values = {{"sample-period", "0.01"}, {"table-memory", "64"}};
  const ObserverSpec s1 = build_design(a, "finite-time", o), s2 = build_design(a, "finite-time", o);
  ASSERT_EQ(s1.tables.size(), s2.tables.size());
  for (std::size_t i = 0; i < s1.tables.size(); ++i)
    EXPECT_EQ(s1.tables[i].values, s2.tables[i].values) << s1.tables[i].name;
  ASSERT_EQ(s1.report.size(), s2.report.size());
  for (std::size_t i = 0; i < s1.report.size(); ++i)
    EXPECT_EQ(s1.report[i].value, s2.report[i].value);
}

// ---- two outputs (issue 18): the filters are dealt round the outputs ------------------------

// A damped Duffing oscillator with two nonlinear sensors. Filter j is fed y_(j mod 2); the
// oracle is the closed loop (the simulator's error against the design's own sampled bound) and
// the generated C++ and C99 steps against the simulator on the same plant samples.
const char* kTwoOutputModel = R"(model ft2
states x1 x2
inputs u
f = [ x2, -x1 - 0.5*x2 - x1^3 ]
g = [ 0, u ]
h = [ sin(x1), x1 + x2 ]
domain x1 in [-1, 1], x2 in [-1, 1], u in [-1, 1]
)";

TEST(FiniteTime, TwoOutputsConvergeAndGeneratedCodeMatchesSimulator) {
  const Analysis a = analyse(parse_model(kTwoOutputModel, "ft2.sym"));
  DesignOptions d;
  d.values = {{"sample-period", "0.01"}, {"table-memory", "64"}};
  const ObserverSpec spec = build_design(a, "finite-time", d);
  ASSERT_TRUE(spec.sampled_delay.has_value());
  EXPECT_EQ(spec.sampled_delay->outputs, 2u);
  SimulationOptions o;
  o.method = "finite-time";
  o.design = d;
  o.u_text = "0.5*sin(t)";
  o.x0 = {0.5, -0.3};
  o.xhat0 = {0, 0};
  o.t_end = 10;
  o.dt = 0.01;
  const SimulationResult r = simulate(a, o);
  ASSERT_TRUE(r.diverged.empty()) << r.diverged;
  // After the window has passed, the error stays within 10 % of the box width (the design's
  // sampled bound at this budget is a few per cent; the box is 2 wide).
  double late = 0;
  for (std::size_t i = r.t.size() / 2; i < r.t.size(); ++i)
    for (std::size_t s = 0; s < 2; ++s) late = std::max(late, std::fabs(r.x[i][s] - r.xh[i][s]));
  std::printf("two outputs: max |x - xh| over the second half %.3g\n", late);
  EXPECT_LT(late, 0.2);
  EXPECT_GT(std::fabs(r.x[0][0] - r.xh[0][0]), 0.4);  // it did start away

  const fs::path dir = fs::temp_directory_path() / ("obsynth_ft2_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  { std::ofstream(dir / "sim.csv") << r.csv; }
  const std::string flags =
      "-Wall -Wextra -Werror -Wconversion -Wdouble-promotion -pedantic -O2 -fno-math-errno";
  EmitOptions eo;
  eo.source_name = "ft2.sym";
  for (bool c : {false, true}) {
    SCOPED_TRACE(c ? "C99" : "C++");
    std::string out;
    if (!c) {
      const EmittedHeader h = emit_cxx_header(a, spec, eo);
      std::ofstream(dir / h.filename) << h.text;
      std::ofstream(dir / "driver.cpp")
          << cxx_defines("ft2", "Ft2FiniteTime", "0.5 * std::sin(t)") << kCxxDriver;
      out = run(
          fmt::format("c++ -std=c++17 {} -fno-exceptions -fno-rtti -DEIGEN_NO_MALLOC -I{}/runtime "
                      "-I/usr/include/eigen3 -DHEADER='\"{}\"' -DSCALAR=double {} -o {}",
                      flags, OBSYNTH_SOURCE_DIR, (dir / h.filename).string(),
                      (dir / "driver.cpp").string(), (dir / "drv_cxx").string()));
    } else {
      const EmittedHeader h = emit_c_pair(a, spec, eo);
      std::ofstream(dir / h.filename) << h.text;
      std::ofstream(dir / h.source_filename) << h.source_text;
      std::ofstream(dir / "driver.c")
          << c_defines("ft2_finite_time_", 2, "0.5 * sin(t)") << kCDriver;
      out = run(fmt::format("cc -std=c99 {} -I{} -I{}/runtime -DHEADER='\"{}\"' {} {} -lm -o {}",
                            flags, dir.string(), OBSYNTH_SOURCE_DIR, h.filename,
                            (dir / h.source_filename).string(), (dir / "driver.c").string(),
                            (dir / "drv_c").string()));
    }
    ASSERT_EQ(out.find("FAILED"), std::string::npos) << out;
    out = run((dir / (c ? "drv_c" : "drv_cxx")).string() + " " + (dir / "sim.csv").string());
    ASSERT_EQ(out.find("FAILED"), std::string::npos) << out.substr(0, 400);
    const auto got = read_pairs(out);
    ASSERT_EQ(got.size(), r.t.size());
    double worst = 0;
    for (std::size_t i = 0; i + 1 < got.size(); ++i)
      for (std::size_t s = 0; s < 2; ++s)
        worst = std::max(worst, std::fabs(got[i][s] - r.xh[i + 1][s]));
    EXPECT_LE(worst, 1e-9);
  }
  fs::remove_all(dir);
}

}  // namespace
