// obsynth command line. The only place that touches argv, files and the process.
#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <cstdio>
#include <iostream>

#include "analysis.hpp"
#include "cxx.hpp"
#include "diagnostics.hpp"
#include "output_dir.hpp"
#include "parse.hpp"
#include "report.hpp"
#include "simulate.hpp"
#include "synthesize.hpp"
#include "worker.hpp"

#ifndef OBSYNTH_VERSION
#define OBSYNTH_VERSION "0.0.0"
#endif

namespace {

using namespace obsynth;

struct CommonOptions {
  double stage_seconds = 60.0;
  std::size_t max_expression_size = 2000000;
  bool in_process = false;
};

void add_common(CLI::App* app, CommonOptions& c) {
  app->add_option("--stage-seconds", c.stage_seconds, "time budget per analysis stage, in seconds")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  app->add_option("--max-expression-size", c.max_expression_size,
                  "largest expression (tree nodes) a stage may store")
      ->capture_default_str();
  app->add_flag("--in-process", c.in_process, "run without the watchdog worker (for debugging)");
}

AnalysisOptions analysis_options(const CommonOptions& c) {
  AnalysisOptions o;
  o.budget.stage_seconds = c.stage_seconds;
  o.budget.max_expression_size = c.max_expression_size;
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

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"obsynth: nonlinear observer synthesis from symbolic models"};
  app.set_version_flag("--version", std::string("obsynth ") + OBSYNTH_VERSION);
  app.require_subcommand(0, 1);

  CommonOptions common;
  std::string check_model, format = "text";
  bool no_timings = false;
  auto* check = app.add_subcommand("check", "analyse a model: observability, brackets, T, l");
  check->add_option("model", check_model, "the .sym model file")->required();
  check->add_option("--format", format, "report format")
      ->check(CLI::IsMember({"text", "json", "markdown", "latex"}))
      ->capture_default_str();
  check->add_flag("--no-timings", no_timings,
                  "omit stage timings (byte-identical output between runs)");
  add_common(check, common);

  std::string sim_model, sim_method = "canonical", sim_u = "0", sim_x0, sim_xhat0, sim_out,
                         sim_poles, sim_realisation, sim_sampling = "continuous";
  double sim_t_end = 10, sim_dt = 1e-3, sim_epsilon = 0.01;
  auto* sim = app.add_subcommand("simulate",
                                 "simulate plant and observer side by side; writes CSV and SVG");
  sim->add_option("model", sim_model, "the .sym model file")->required();
  sim->add_option("--method", sim_method, "canonical or perfect")->capture_default_str();
  sim->add_option("--u", sim_u, "input(s) as expressions in t, comma-separated")
      ->capture_default_str();
  sim->add_option("--x0", sim_x0, "initial plant state, comma-separated")->required();
  sim->add_option("--xhat0", sim_xhat0, "initial estimate, comma-separated")->required();
  sim->add_option("--t-end", sim_t_end, "horizon")->capture_default_str();
  sim->add_option("--dt", sim_dt, "step")->capture_default_str();
  sim->add_option("--poles", sim_poles, "canonical observer poles");
  sim->add_option("--realisation", sim_realisation, "z or x")->check(CLI::IsMember({"z", "x"}));
  sim->add_option(
         "--sampling", sim_sampling,
         "continuous: plant and observer as one ODE; zoh: the firmware step() with u, y held")
      ->check(CLI::IsMember({"continuous", "zoh"}))
      ->capture_default_str();
  sim->add_option("--epsilon", sim_epsilon, "perfect observer: differentiator time constant")
      ->capture_default_str();
  sim->add_option("-o,--output", sim_out, "output directory for <model>_<method>.csv and .svg")
      ->required();
  CommonOptions sim_common;
  add_common(sim, sim_common);

  // The main job: obsynth model.sym -o out/
  std::string model_path, out_dir, methods = "auto", precision = "double", poles, realisation;
  app.add_option("model", model_path, "the .sym model file (main job: generate observers)");
  app.add_option("-o,--output", out_dir, "output directory for headers and reports");
  app.add_option("--method", methods,
                 "auto, or a comma-separated list of: canonical, perfect (riccati, high-gain, "
                 "kalman-theta, thau, kou, extended-linearization, finite-time: planned)")
      ->capture_default_str();
  app.add_option("--precision", precision,
                 "literal precision and default scalar of the generated code")
      ->check(CLI::IsMember({"float", "double"}))
      ->capture_default_str();
  app.add_option("--poles", poles,
                 "canonical observer error poles, comma-separated negative reals "
                 "(default -2, -2.5, -3, ...)");
  app.add_option("--realisation", realisation,
                 "canonical observer realisation: z or x (default: z when T^-1 is closed-form)")
      ->check(CLI::IsMember({"z", "x"}));
  CommonOptions main_common;
  add_common(&app, main_common);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 1;
  }

  if (*check) {
    return guarded(common, [&] {
      const Model m = load_model(check_model);
      const Analysis a = analyse(m, analysis_options(common));
      const ReportFormat f = format == "json"       ? ReportFormat::json
                             : format == "markdown" ? ReportFormat::markdown
                             : format == "latex"    ? ReportFormat::latex
                                                    : ReportFormat::text;
      ReportOptions ro;
      ro.timings = !no_timings;
      std::fputs(render_report(a, f, ro).c_str(), stdout);
      return 0;
    });
  }
  if (*sim) {
    return guarded(sim_common, [&] {
      SimulationOptions so;
      so.method = sim_method;
      so.u_text = sim_u;
      for (const auto& v : split_list(sim_x0)) so.x0.push_back(parse_real(v, "--x0").to_double());
      for (const auto& v : split_list(sim_xhat0))
        so.xhat0.push_back(parse_real(v, "--xhat0").to_double());
      so.t_end = sim_t_end;
      so.dt = sim_dt;
      so.epsilon = sim_epsilon;
      so.sampling = sim_sampling == "zoh" ? Sampling::zoh : Sampling::continuous;
      for (const auto& p : split_list(sim_poles))
        so.canonical.poles.push_back(parse_real(p, "--poles"));
      if (!sim_realisation.empty())
        so.canonical.realisation = sim_realisation == "z" ? Realisation::z : Realisation::x;
      const Model m = load_model(sim_model);
      const Analysis a = analyse(m, analysis_options(sim_common));
      const SimulationResult r = simulate(a, so);
      const std::string stem = cxx_identifier(m.name) + "_" + sim_method;
      write_output_dir(sim_out, {{stem + ".csv", r.csv}, {stem + ".svg", r.svg}});
      std::printf("wrote %s/%s.csv and %s.svg\n%s\n", sim_out.c_str(), stem.c_str(), stem.c_str(),
                  r.summary.c_str());
      return 0;
    });
  }
  if (!model_path.empty()) {
    if (out_dir.empty()) {
      std::fprintf(stderr,
                   "obsynth: error: the main job needs an output directory: obsynth %s -o out/\n",
                   model_path.c_str());
      return 1;
    }
    return guarded(main_common, [&] {
      SynthesisOptions so;
      so.methods = split_list(methods);
      so.emit.precision = precision == "float" ? Precision::single : Precision::double_precision;
      so.emit.source_name = model_path;
      for (const auto& p : split_list(poles))
        so.canonical.poles.push_back(parse_real(p, "--poles"));
      if (!realisation.empty())
        so.canonical.realisation = realisation == "z" ? Realisation::z : Realisation::x;
      const Model m = load_model(model_path);
      const Analysis a = analyse(m, analysis_options(main_common));
      const Synthesis s = synthesize(a, so);
      write_output_dir(out_dir, s.files);
      for (const auto& f : s.files) std::printf("wrote %s/%s\n", out_dir.c_str(), f.name.c_str());
      if (!s.explanation.empty()) std::printf("%s\n", s.explanation.c_str());
      return 0;
    });
  }
  std::fputs(app.help().c_str(), stdout);
  return 0;
}
