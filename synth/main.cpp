// obsynth command line. The only place that touches argv, files and the process.
#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <cstdio>
#include <iostream>

#include "analysis/analysis.hpp"
#include "app/output_dir.hpp"
#include "app/report.hpp"
#include "app/simulate.hpp"
#include "app/synthesize.hpp"
#include "app/worker.hpp"
#include "emit/cxx.hpp"
#include "front/diagnostics.hpp"
#include "front/parse.hpp"

#ifndef OBSYNTH_VERSION
#define OBSYNTH_VERSION "0.0.0"
#endif

namespace {

using namespace obsynth;

struct CommonOptions {
  double stage_seconds = 60.0;
  std::size_t max_expression_size = 2000000;
  bool in_process = false;
  std::string rank_method = "auto";
};

void add_common(CLI::App* app, CommonOptions& c) {
  app->add_option("--stage-seconds", c.stage_seconds, "time budget per analysis stage, in seconds")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  app->add_option("--max-expression-size", c.max_expression_size,
                  "largest expression (tree nodes) a stage may store")
      ->capture_default_str();
  app->add_flag("--in-process", c.in_process, "run without the watchdog worker (for debugging)");
  app->add_option("--rank-method", c.rank_method,
                  "observability rank: symbolic, jets (Taylor jets at random points), or auto "
                  "(symbolic; jets when the Lie derivatives exceed their budget)")
      ->check(CLI::IsMember({"auto", "symbolic", "jets"}))
      ->capture_default_str();
}

AnalysisOptions analysis_options(const CommonOptions& c) {
  AnalysisOptions o;
  o.budget.stage_seconds = c.stage_seconds;
  o.budget.max_expression_size = c.max_expression_size;
  o.on_stage = publish_stage;
  o.observability.rank_method = c.rank_method == "jets"       ? RankMethod::jets
                                : c.rank_method == "symbolic" ? RankMethod::symbolic
                                                              : RankMethod::automatic;
  return o;
}

// Runs a job, turning exceptions into diagnostics and exit codes, under the watchdog.
int guarded(const CommonOptions& c, const std::function<int()>& job) {
  auto body = [&]() -> int {
    try {
      return job();
    } catch (const UserError& e) {
      for (const auto& d : e.diagnostics())
        std::fprintf(stderr, "%s\n", format_diagnostic(d).c_str());
      return 1;
    } catch (const InternalError& e) {
      std::fprintf(stderr, "obsynth: %s\n", e.what());
      return 2;
    } catch (const std::exception& e) {
      std::fprintf(stderr, "obsynth: internal error: %s\n", e.what());
      return 2;
    }
  };
  if (c.in_process) return body();
  const WorkerResult r = run_in_worker(body, c.stage_seconds);
  if (r.timed_out) {
    std::fprintf(stderr,
                 "obsynth: error: stage '%s' exceeded its time budget of %g s (raise it with "
                 "--stage-seconds)\n",
                 r.stage.c_str(), c.stage_seconds);
    return 1;
  }
  return r.exit_code;
}

std::vector<std::string> split_list(const std::string& s) {
  std::vector<std::string> out;
  std::string cur;
  for (char c : s) {
    if (c == ',') {
      if (!cur.empty()) out.push_back(cur);
      cur.clear();
    } else if (c != ' ') {
      cur += c;
    }
  }
  if (!cur.empty()) out.push_back(cur);
  return out;
}

// A real number given on the command line, as an exact rational (decimals are exact).
GiNaC::numeric parse_real(const std::string& text, const char* option) {
  try {
    const Model m =
        parse_model("model q\nstates q\nf = [0]\nh = [q]\nparams v = " + text + "\n", option);
    return *m.params[0].value;
  } catch (const UserError&) {
    throw UserError(SourceLoc{}, fmt::format("{}: '{}' is not a real number", option, text));
  }
}

struct CheckCommand {
  std::string model, format = "text";
  bool no_timings = false;
  CommonOptions common;
};

struct SimulateCommand {
  std::string model, method = "canonical", u = "0", x0, xhat0, out, poles, realisation,
                     sampling = "continuous";
  double t_end = 10, dt = 1e-3, epsilon = 0.01;
  CommonOptions common;
};

struct MainJob {
  std::string model, out, methods = "auto", precision = "double", poles, realisation;
  CommonOptions common;
};

CLI::App* add_check(CLI::App& app, CheckCommand& c) {
  auto* check = app.add_subcommand("check", "analyse a model: observability, brackets, T, l");
  check->add_option("model", c.model, "the .sym model file")->required();
  check->add_option("--format", c.format, "report format")
      ->check(CLI::IsMember({"text", "json", "markdown", "latex"}))
      ->capture_default_str();
  check->add_flag("--no-timings", c.no_timings,
                  "omit stage timings (byte-identical output between runs)");
  add_common(check, c.common);
  return check;
}

CLI::App* add_simulate(CLI::App& app, SimulateCommand& c) {
  auto* sim = app.add_subcommand("simulate",
                                 "simulate plant and observer side by side; writes CSV and SVG");
  sim->add_option("model", c.model, "the .sym model file")->required();
  sim->add_option("--method", c.method, "canonical or perfect")->capture_default_str();
  sim->add_option("--u", c.u, "input(s) as expressions in t, comma-separated")
      ->capture_default_str();
  sim->add_option("--x0", c.x0, "initial plant state, comma-separated")->required();
  sim->add_option("--xhat0", c.xhat0, "initial estimate, comma-separated")->required();
  sim->add_option("--t-end", c.t_end, "horizon")->capture_default_str();
  sim->add_option("--dt", c.dt, "step")->capture_default_str();
  sim->add_option("--poles", c.poles, "canonical observer poles");
  sim->add_option("--realisation", c.realisation, "z or x")->check(CLI::IsMember({"z", "x"}));
  sim->add_option(
         "--sampling", c.sampling,
         "continuous: plant and observer as one ODE; zoh: the firmware step() with u, y held")
      ->check(CLI::IsMember({"continuous", "zoh"}))
      ->capture_default_str();
  sim->add_option("--epsilon", c.epsilon, "perfect observer: differentiator time constant")
      ->capture_default_str();
  sim->add_option("-o,--output", c.out, "output directory for <model>_<method>.csv and .svg")
      ->required();
  add_common(sim, c.common);
  return sim;
}

void add_main_job(CLI::App& app, MainJob& c) {
  app.add_option("model", c.model, "the .sym model file (main job: generate observers)");
  app.add_option("-o,--output", c.out, "output directory for headers and reports");
  app.add_option("--method", c.methods,
                 "auto, or a comma-separated list of: canonical, perfect (riccati, high-gain, "
                 "kalman-theta, thau, kou, extended-linearization, finite-time: planned)")
      ->capture_default_str();
  app.add_option("--precision", c.precision,
                 "literal precision and default scalar of the generated code")
      ->check(CLI::IsMember({"float", "double"}))
      ->capture_default_str();
  app.add_option("--poles", c.poles,
                 "canonical observer error poles, comma-separated negative reals "
                 "(default -2, -2.5, -3, ...)");
  app.add_option("--realisation", c.realisation,
                 "canonical observer realisation: z or x (default: z when T^-1 is closed-form)")
      ->check(CLI::IsMember({"z", "x"}));
  add_common(&app, c.common);
}

ReportFormat report_format(const std::string& name) {
  return name == "json"       ? ReportFormat::json
         : name == "markdown" ? ReportFormat::markdown
         : name == "latex"    ? ReportFormat::latex
                              : ReportFormat::text;
}

int run_check(const CheckCommand& c) {
  return guarded(c.common, [&] {
    const Model m = load_model(c.model);
    const Analysis a = analyse(m, analysis_options(c.common));
    ReportOptions ro;
    ro.timings = !c.no_timings;
    std::fputs(render_report(a, report_format(c.format), ro).c_str(), stdout);
    return 0;
  });
}

int run_simulate(const SimulateCommand& c) {
  return guarded(c.common, [&] {
    SimulationOptions so;
    so.method = c.method;
    so.u_text = c.u;
    for (const auto& v : split_list(c.x0)) so.x0.push_back(parse_real(v, "--x0").to_double());
    for (const auto& v : split_list(c.xhat0))
      so.xhat0.push_back(parse_real(v, "--xhat0").to_double());
    so.t_end = c.t_end;
    so.dt = c.dt;
    so.epsilon = c.epsilon;
    so.sampling = c.sampling == "zoh" ? Sampling::zoh : Sampling::continuous;
    for (const auto& p : split_list(c.poles))
      so.canonical.poles.push_back(parse_real(p, "--poles"));
    if (!c.realisation.empty())
      so.canonical.realisation = c.realisation == "z" ? Realisation::z : Realisation::x;
    const Model m = load_model(c.model);
    const Analysis a = analyse(m, analysis_options(c.common));
    const SimulationResult r = simulate(a, so);
    const std::string stem = cxx_identifier(m.name) + "_" + c.method;
    write_output_dir(c.out, {{stem + ".csv", r.csv}, {stem + ".svg", r.svg}});
    std::printf("wrote %s/%s.csv and %s.svg\n%s\n", c.out.c_str(), stem.c_str(), stem.c_str(),
                r.summary.c_str());
    return 0;
  });
}

int run_main_job(const MainJob& c) {
  if (c.out.empty()) {
    std::fprintf(stderr,
                 "obsynth: error: the main job needs an output directory: obsynth %s -o out/\n",
                 c.model.c_str());
    return 1;
  }
  return guarded(c.common, [&] {
    SynthesisOptions so;
    so.methods = split_list(c.methods);
    so.emit.precision = c.precision == "float" ? Precision::single : Precision::double_precision;
    so.emit.source_name = c.model;
    for (const auto& p : split_list(c.poles))
      so.canonical.poles.push_back(parse_real(p, "--poles"));
    if (!c.realisation.empty())
      so.canonical.realisation = c.realisation == "z" ? Realisation::z : Realisation::x;
    const Model m = load_model(c.model);
    const Analysis a = analyse(m, analysis_options(c.common));
    const Synthesis s = synthesize(a, so);
    write_output_dir(c.out, s.files);
    for (const auto& f : s.files) std::printf("wrote %s/%s\n", c.out.c_str(), f.name.c_str());
    if (!s.explanation.empty()) std::printf("%s\n", s.explanation.c_str());
    return 0;
  });
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"obsynth: nonlinear observer synthesis from symbolic models"};
  app.set_version_flag("--version", std::string("obsynth ") + OBSYNTH_VERSION);
  app.require_subcommand(0, 1);
  CheckCommand check;
  SimulateCommand sim;
  MainJob job;
  auto* check_cmd = add_check(app, check);
  auto* sim_cmd = add_simulate(app, sim);
  add_main_job(app, job);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 1;
  }
  if (*check_cmd) return run_check(check);
  if (*sim_cmd) return run_simulate(sim);
  if (!job.model.empty()) return run_main_job(job);
  std::fputs(app.help().c_str(), stdout);
  return 0;
}
