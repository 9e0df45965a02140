// obsynth command line. The only place that touches argv, files and the process.
#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <cstdio>
#include <iostream>

#include "analysis.hpp"
#include "diagnostics.hpp"
#include "parse.hpp"
#include "report.hpp"
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
      for (const auto& d : e.diagnostics()) std::fprintf(stderr, "%s\n", format_diagnostic(d).c_str());
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
  check->add_flag("--no-timings", no_timings, "omit stage timings (byte-identical output between runs)");
  add_common(check, common);

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
  std::fputs(app.help().c_str(), stdout);
  return 0;
}
