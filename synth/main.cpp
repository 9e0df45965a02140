// obsynth command line. The only place that touches argv, files and the process.
#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <cstdio>
#include <iostream>
#include <optional>

#include "analysis/analysis.hpp"
#include "analysis/persistence.hpp"
#include "app/design_report.hpp"
#include "app/output_dir.hpp"
#include "app/report.hpp"
#include "app/simulate.hpp"
#include "app/stages.hpp"
#include "app/synthesize.hpp"
#include "app/worker.hpp"
#include "designs/registry.hpp"
#include "emit/cxx.hpp"
#include "foundation/diagnostics.hpp"
#include "front/bind.hpp"
#include "front/parse.hpp"
#include "symbolic/expr_print.hpp"

#ifndef OBSYNTH_VERSION
#define OBSYNTH_VERSION "0.0.0"
#endif

namespace {

using namespace obsynth;

struct CommonOptions {
  double stage_seconds = 60.0;
  double canonical_seconds = kCanonicalStageSeconds;
  double total_seconds = 60.0;
  std::size_t max_expression_size = 2000000;
  std::size_t max_memory_bytes = default_memory_budget();
  bool in_process = false;
  std::string rank_method = "auto";
};

// --max-memory SIZE: a CLI11 transform that replaces the text by the number of bytes, or
// returns the diagnostic.
CLI::Validator memory_size() {
  constexpr std::size_t minimum = std::size_t{32} << 20;
  return CLI::Validator(
      [](std::string& text) -> std::string {
        const auto bytes = parse_memory_size(text);
        if (!bytes)
          return fmt::format(
              "'{}' is not a memory size: write a number and a unit K, M, G or T, "
              "e.g. 512M or 4G",
              text);
        if (*bytes < minimum)
          return fmt::format("'{}' is {} bytes, below the minimum of {}", text, *bytes,
                             format_memory_size(minimum));
        text = std::to_string(*bytes);
        return {};
      },
      "");
}

void add_common(CLI::App* app, CommonOptions& c) {
  app->add_option("--stage-seconds", c.stage_seconds, "time budget per analysis stage, in seconds")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  app->add_option("--canonical-seconds", c.canonical_seconds,
                  "time budget of each canonical-form stage (frame, conditions, diffeomorphism; "
                  "at most --stage-seconds): auto and all go on without them after a stop")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  app->add_option("--total-seconds", c.total_seconds,
                  "time budget of the whole run, in seconds: it ends within it (with the results "
                  "of the stages completed so far, exit 1)")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  app->add_option("--max-expression-size", c.max_expression_size,
                  "largest expression (tree nodes) a stage may store")
      ->capture_default_str();
  app->add_option("--max-memory", c.max_memory_bytes,
                  fmt::format("memory budget (address space) of the analysis, e.g. 512M or 4G; "
                              "default: half of physical memory, {}",
                              format_memory_size(c.max_memory_bytes)))
      ->type_name("SIZE")
      ->transform(memory_size());
  app->add_flag("--in-process", c.in_process,
                "run without the watchdog (no time budget; for debugging)");
  app->add_option("--rank-method", c.rank_method,
                  "observability rank: symbolic, jets (Taylor jets at random points), or auto "
                  "(symbolic; jets when the Lie derivatives exceed their budget)")
      ->check(CLI::IsMember({"auto", "symbolic", "jets"}))
      ->capture_default_str();
}

AnalysisOptions analysis_options(const CommonOptions& c) {
  AnalysisOptions o;
  o.budget.stage_seconds = c.stage_seconds;
  o.budget.canonical_stage_seconds = c.canonical_seconds;
  o.budget.max_expression_size = c.max_expression_size;
  o.budget.max_memory_bytes = c.max_memory_bytes;
  o.on_stage = publish_stage;
  o.observability.rank_method = c.rank_method == "jets"       ? RankMethod::jets
                                : c.rank_method == "symbolic" ? RankMethod::symbolic
                                                              : RankMethod::automatic;
  return o;
}

// Whether the methods asked for (a comma-separated list) need the canonical-form stages:
// auto, all and names not registered keep the full analysis.
bool need_canonical_form(const std::vector<std::string>& methods) {
  for (const auto& name : methods) {
    const Design* d = find_design(name);
    if (!d || d->needs_canonical_form) return true;
  }
  return methods.empty();
}

void print_stop(const std::string& stage, const std::string& reason) {
  std::fprintf(stderr, "obsynth: error: stage '%s' %s\n", stage.c_str(), reason.c_str());
}

// Runs a job, turning exceptions into diagnostics and exit codes, under a watchdog.
// Every budget stop (time, size, memory; in the analysis, the worker or this process) ends in
// "obsynth: error: stage 'X' <reason>" and exit 1, after the partial report a checkpoint left.
// When `stopped` is given, a stage's time or memory stop of the worker fills it instead of
// printing the diagnostic, so that the caller can decide what follows (a stop of the total time
// budget ends the run).
struct JobStop {
  std::string stage, reason;
  std::string checkpoint;  // the partial report the worker left (reason filled in)
};
int guarded(const CommonOptions& c, const std::function<int()>& job,
            std::optional<JobStop>* stopped = nullptr) {
  auto body = [&]() -> int {
    try {
      return job();
    } catch (const BudgetExceeded& e) {
      print_stop(e.stage(), e.reason());
      return 1;
    } catch (const UserError& e) {
      for (const auto& d : e.diagnostics())
        std::fprintf(stderr, "%s\n", format_diagnostic(d).c_str());
      return 1;
    } catch (const InternalError& e) {
      std::fprintf(stderr, "obsynth: %s\n", e.what());
      return 2;
    } catch (const std::exception& e) {
      if (is_out_of_memory(e)) {
        print_stop(current_stage(), memory_budget_reason(c.max_memory_bytes));
        return 1;
      }
      std::fprintf(stderr, "obsynth: internal error: %s\n", e.what());
      return 2;
    }
  };
  if (c.in_process) return run_in_process(body, c.max_memory_bytes);
  // A stop that ends the process needs no second process: a watchdog thread prints the
  // checkpoint and the diagnostic itself. Only a caller that goes on after it needs the fork.
  const WorkerLimits limits{c.stage_seconds, c.max_memory_bytes, c.total_seconds,
                            c.canonical_seconds};
  if (!stopped) return run_watched(body, limits);
  const WorkerResult r = run_in_worker(body, limits);
  if (r.stop != WorkerStop::none) {
    const std::string reason =
        r.stop == WorkerStop::time
            ? stage_time_budget_reason(r.stage, c.stage_seconds, c.canonical_seconds)
        : r.stop == WorkerStop::total_time ? total_time_budget_reason(c.total_seconds)
                                           : memory_budget_reason(c.max_memory_bytes);
    const std::string checkpoint = fill_checkpoint(r.checkpoint, reason);
    if (stopped && r.stop != WorkerStop::total_time) {  // the total budget admits no rerun
      *stopped = JobStop{r.stage, reason, checkpoint};  // the caller prints it, or reruns
      return 1;
    }
    std::fputs(checkpoint.c_str(), stdout);
    std::fflush(stdout);
    print_stop(r.stage, reason);
    return 1;
  }
  if (r.signal != 0)
    std::fprintf(stderr, "obsynth: internal error: the worker died of signal %d in stage '%s'\n",
                 r.signal, r.stage.c_str());
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

// Design options (--poles, --realisation, ...) come from the registry: each design declares
// its own, and every subcommand that builds designs accepts them all.
void add_design_options(CLI::App* app, DesignOptions& o) {
  for (const auto& info : all_design_options()) {
    auto* opt = app->add_option("--" + info.name, o.values[info.name], info.help);
    if (!info.default_text.empty()) opt->default_str(info.default_text);
    // --<design>.<option>: accepted, listed by --list-methods --format json, not in --help
    // (one line per design and option would bury the bare ones).
    if (info.name.find('.') != std::string::npos) opt->group("");
  }
}

// Only the options actually given.
DesignOptions given(const DesignOptions& o) {
  DesignOptions out;
  for (const auto& [k, v] : o.values)
    if (!v.empty()) out.values[k] = v;
  return out;
}

void add_param_option(CLI::App* app, std::vector<std::string>& params) {
  app->add_option("--param", params,
                  "bind a free parameter at synthesis time, name=value (repeatable); unbound "
                  "free parameters are run-time fields of the generated class");
}

std::string method_help() {
  std::vector<std::string> names;
  for (const auto& d : design_registry()) names.push_back(d.name);
  return fmt::format(
      "auto, all (every design that applies), or a comma-separated list of: {} (planned: {})",
      fmt::join(names, ", "), fmt::join(planned_methods(), ", "));
}

Model load_bound_model(const std::string& path, const std::vector<std::string>& params) {
  return bind_parameters(load_model(path), params);
}

struct CheckCommand {
  std::string model, format = "text";
  std::string input;  // strong persistence check along this input (seed 002)
  double horizon = 20;
  std::string thetas;
  bool no_timings = false;
  // also the costly verdicts: certificate searches (thau, kou), the symbolic extended
  // linearization
  bool certify = false;
  std::vector<std::string> params;
  CommonOptions common;
};

struct SimulateCommand {
  std::string model, method = "auto", u = "0", x0, xhat0, out, sampling = "continuous";
  double t_end = 10, dt = 1e-3;
  std::vector<std::string> params, plant_params;
  DesignOptions design;
  CommonOptions common;
};

struct MainJob {
  std::string model, out, methods = "auto", precision = "double", language = "cpp";
  std::vector<std::string> params;
  DesignOptions design;
  bool list_methods = false;
  std::string list_format = "text";
  CommonOptions common;
};

CLI::App* add_check(CLI::App& app, CheckCommand& c) {
  auto* check = app.add_subcommand("check", "analyse a model: observability, brackets, T, l");
  check->add_option("model", c.model, "the .sym model file")->required();
  check->add_option("--format", c.format, "report format")
      ->check(CLI::IsMember({"text", "json", "markdown", "latex"}))
      ->capture_default_str();
  check->add_flag("--certify", c.certify,
                  "also run the costly design verdicts: certificate searches (thau, kou) and the "
                  "symbolic extended linearization (up to seconds each)");
  check->add_flag("--no-timings", c.no_timings,
                  "omit stage timings (byte-identical output between runs)");
  check->add_option("--input", c.input,
                    "strong persistence check (seed 002) along this input: expressions in t, "
                    "one per input; JSON key \"persistence\"");
  check->add_option("--horizon", c.horizon, "horizon of the persistence check")
      ->capture_default_str();
  check->add_option("--thetas", c.thetas,
                    "theta values of the persistence check, comma-separated (default 1, 2, 5, "
                    "10, 20, 50)");
  add_param_option(check, c.params);
  add_common(check, c.common);
  return check;
}

CLI::App* add_simulate(CLI::App& app, SimulateCommand& c) {
  auto* sim = app.add_subcommand("simulate",
                                 "simulate plant and observer side by side; writes CSV and SVG");
  sim->add_option("model", c.model, "the .sym model file")->required();
  sim->add_option("--method", c.method, method_help())->capture_default_str();
  sim->add_option("--u", c.u, "input(s) as expressions in t, comma-separated")
      ->capture_default_str();
  sim->add_option("--x0", c.x0, "initial plant state, comma-separated")->required();
  sim->add_option("--xhat0", c.xhat0, "initial estimate, comma-separated")->required();
  sim->add_option("--t-end", c.t_end, "horizon")->capture_default_str();
  sim->add_option("--dt", c.dt, "step")->capture_default_str();
  sim->add_option(
         "--sampling", c.sampling,
         "continuous: plant and observer as one ODE; zoh: the firmware step() with u, y held")
      ->check(CLI::IsMember({"continuous", "zoh"}))
      ->capture_default_str();
  sim->add_option("-o,--output", c.out, "output directory for <model>_<method>.csv and .svg")
      ->required();
  add_design_options(sim, c.design);
  add_param_option(sim, c.params);
  sim->add_option("--plant-param", c.plant_params,
                  "a free parameter's value in the plant alone, name=value (repeatable); the "
                  "observer keeps its own (--param, else its run-time default)");
  add_common(sim, c.common);
  return sim;
}

void add_main_job(CLI::App& app, MainJob& c) {
  app.add_option("model", c.model, "the .sym model file (main job: generate observers)");
  app.add_option("-o,--output", c.out, "output directory for headers and reports");
  app.add_option("--method", c.methods, method_help())->capture_default_str();
  app.add_option("--precision", c.precision,
                 "literal precision and default scalar of the generated code")
      ->check(CLI::IsMember({"float", "double"}))
      ->capture_default_str();
  app.add_option("--language", c.language,
                 "language of the generated code: cpp (one header) or c (C99 .h and .c)")
      ->check(CLI::IsMember({"cpp", "c"}))
      ->capture_default_str();
  app.add_flag("--list-methods", c.list_methods, "list the observer designs and exit");
  app.add_option("--format", c.list_format,
                 "with --list-methods: text, or json (traits and options of every design)")
      ->check(CLI::IsMember({"text", "json"}))
      ->capture_default_str();
  add_design_options(&app, c.design);
  add_param_option(&app, c.params);
  add_common(&app, c.common);
}

ReportFormat report_format(const std::string& name) {
  return name == "json"       ? ReportFormat::json
         : name == "markdown" ? ReportFormat::markdown
         : name == "latex"    ? ReportFormat::latex
                              : ReportFormat::text;
}

int list_methods(const std::string& format) {
  if (format == "json") {
    std::printf("%s\n", methods_json().dump(2).c_str());
    return 0;
  }
  for (const auto& d : design_registry())
    std::printf("%-24s %s\n", d.name.c_str(), d.summary.c_str());
  for (const auto& p : planned_methods())
    std::printf("%-24s planned (not implemented in this version)\n", p.c_str());
  return 0;
}

// A budget stop still prints the results of the completed stages (through checkpoints when
// the worker has to be killed), then the diagnostic, exit 1: the report is partial. A
// complete analysis also gets the design verdicts.
// canonical_stop: a budget stopped a canonical-form stage in an earlier run; this one skips
// those stages (with that reason) and reports everything else, with that stage marked stopped
// (the report is partial: "complete": false) and the design verdicts.
struct CanonicalStop {
  std::string stage, reason;
  std::string text() const { return fmt::format("stage '{}' {}", stage, reason); }
};

// The rerun's stage list says what the first run found: that stage stopped, the canonical-form
// stages after it did not run.
void mark_canonical_stop(Analysis& a, const CanonicalStop& stop) {
  bool after = false;
  for (auto& o : a.stages) {
    if (o.name == stop.stage) {
      o.status = StageStatus::stopped;
      o.reason = stop.reason;
      after = true;
    } else if (after && is_canonical_form_stage(o.name)) {
      o.status = StageStatus::not_run;
      o.reason = "an earlier stage was stopped";
    }
  }
}

int check_body(const CheckCommand& c, const std::optional<CanonicalStop>& canonical_stop) {
  {
    const Model m = load_bound_model(c.model, c.params);
    ReportOptions ro;
    ro.timings = !c.no_timings;
    const ReportFormat format = report_format(c.format);
    AnalysisOptions ao = analysis_options(c.common);
    ao.keep_partial = true;
    if (canonical_stop) {
      ao.canonical_form = false;
      ao.canonical_skipped = canonical_stop->text();
    }
    ao.checkpoint_reason = kStopReasonMarker;
    PrintCache printed;  // checkpoints and the final report print each expression once
    ao.on_checkpoint = [&](const Analysis& partial) {
      PrintCache::Use use(printed);
      publish_checkpoint(render_report(partial, format, ro));
    };
    Analysis a = analyse(m, ao);
    publish_checkpoint("");
    if (const StageOutcome* s = a.stopped_stage();
        s && !canonical_stop && is_canonical_form_stage(s->name)) {
      // An in-process stop (expression size): the same fallback as the worker's time stop.
      const CanonicalStop stop{s->name, s->reason};
      std::fprintf(stderr, "obsynth: note: %s; the report goes on without the canonical form\n",
                   stop.text().c_str());
      const int rerun = check_body(c, stop);
      if (rerun != 0) return rerun;
      print_stop(stop.stage, stop.reason);
      return 1;
    }
    publish_stage("report");
    PrintCache::Use use(printed);
    const StageOutcome* stopped = a.stopped_stage();  // before the rerun's marks: verdicts stay
    if (canonical_stop) mark_canonical_stop(a, *canonical_stop);
    VerdictScope scope;
    scope.searches = c.certify;
    std::string text = stopped ? render_report(a, format, ro)
                               : render_check(a, format, ro, design_verdicts_json(a, scope));
    if (!c.input.empty() && !stopped) {
      PersistenceOptions po;
      po.input_text = c.input;
      po.horizon = c.horizon;
      po.indices = a.observability.indices;
      if (!c.thetas.empty()) {
        po.thetas.clear();
        for (const auto& v : split_list(c.thetas))
          po.thetas.push_back(parse_real_number(v, "--thetas").to_double());
      }
      const PersistenceResult pr = check_persistence(m, po);
      if (format == ReportFormat::json) {
        auto j = nlohmann::ordered_json::parse(text);
        j["persistence"] = persistence_json(pr);
        text = j.dump(2) + "\n";
      } else {
        text += render_persistence(pr, c.format);
      }
    }
    std::fputs(text.c_str(), stdout);
    if (stopped) {
      std::fflush(stdout);
      print_stop(stopped->name, stopped->reason);
      return 1;
    }
    return 0;
  }
}

// A time or memory stop in a canonical-form stage does not cost the rest of the report: the
// analysis runs again without those stages and reports every design that does not need them,
// then the diagnostic, exit 1 (the report is partial). Other stops end with the checkpoint.
int run_check(const CheckCommand& c) {
  std::optional<JobStop> stop;
  const int code = guarded(
      c.common, [&] { return check_body(c, std::nullopt); }, &stop);
  if (!stop) return code;
  if (!is_canonical_form_stage(stop->stage)) {
    std::fputs(stop->checkpoint.c_str(), stdout);
    std::fflush(stdout);
    print_stop(stop->stage, stop->reason);
    return 1;
  }
  const CanonicalStop canonical{stop->stage, stop->reason};
  std::fprintf(stderr, "obsynth: note: %s; the report goes on without the canonical form\n",
               canonical.text().c_str());
  const int rerun = guarded(c.common, [&] { return check_body(c, canonical); });
  if (rerun != 0) return rerun;
  print_stop(stop->stage, stop->reason);
  return 1;
}

int run_simulate(const SimulateCommand& c) {
  return guarded(c.common, [&] {
    SimulationOptions so;
    so.method = c.method;
    so.design = given(c.design);
    so.u_text = c.u;
    for (const auto& v : split_list(c.x0))
      so.x0.push_back(parse_real_number(v, "--x0").to_double());
    for (const auto& v : split_list(c.xhat0))
      so.xhat0.push_back(parse_real_number(v, "--xhat0").to_double());
    so.t_end = c.t_end;
    so.dt = c.dt;
    so.sampling = c.sampling == "zoh" ? Sampling::zoh : Sampling::continuous;
    const Model unbound = load_model(c.model);
    const Model m = bind_parameters(unbound, c.params);
    so.plant_params = c.plant_params;
    so.unbound_model = &unbound;
    AnalysisOptions ao = analysis_options(c.common);
    ao.canonical_form = need_canonical_form(split_list(c.method));
    const Analysis a = analyse(m, ao);
    const SimulationResult r = simulate(a, so);
    if (!r.explanation.empty()) std::fprintf(stderr, "obsynth: note: %s\n", r.explanation.c_str());
    const std::string stem = cxx_identifier(m.name) + "_" + r.method;
    write_output_dir(c.out, {{stem + ".csv", r.csv}, {stem + ".svg", r.svg}});
    std::printf("wrote %s/%s.csv and %s.svg\n%s\n", c.out.c_str(), stem.c_str(), stem.c_str(),
                r.summary.c_str());
    if (!r.diverged.empty()) {
      std::fprintf(stderr, "obsynth: error: %s\n", r.diverged.c_str());
      return 1;
    }
    return 0;
  });
}

int main_job_body(const MainJob& c, const std::string& canonical_stop,
                  const std::vector<ExcludedDesign>& excluded) {
  SynthesisOptions so;
  so.methods = split_list(c.methods);
  so.auto_excluded = excluded;
  so.design = given(c.design);
  so.emit.precision = c.precision == "float" ? Precision::single : Precision::double_precision;
  so.emit.source_name = c.model;
  so.emit.language = c.language == "c" ? Language::c : Language::cpp;
  const Model m = load_bound_model(c.model, c.params);
  AnalysisOptions ao = analysis_options(c.common);
  ao.canonical_form = need_canonical_form(so.methods) && canonical_stop.empty();
  if (!canonical_stop.empty()) ao.canonical_skipped = canonical_stop;
  Analysis a;
  try {
    a = analyse(m, ao);
  } catch (const BudgetExceeded& e) {  // in-process stops (expression size)
    if (!ao.canonical_form || !may_skip_canonical_form(so.methods) ||
        !is_canonical_form_stage(e.stage()))
      throw;
    std::fprintf(stderr, "obsynth: note: stage '%s' %s; continuing without the canonical form\n",
                 e.stage().c_str(), e.reason().c_str());
    ao.canonical_form = false;
    ao.canonical_skipped = fmt::format("stage '{}' {}", e.stage(), e.reason());
    a = analyse(m, ao);
  }
  const Synthesis s = synthesize(a, so);
  write_output_dir(c.out, s.files);
  std::string dir = c.out;
  while (dir.size() > 1 && dir.back() == '/') dir.pop_back();
  for (const auto& f : s.files) std::printf("wrote %s/%s\n", dir.c_str(), f.name.c_str());
  if (!s.explanation.empty()) std::printf("%s\n", s.explanation.c_str());
  for (const auto& w : s.warnings) std::fprintf(stderr, "obsynth: warning: %s\n", w.c_str());
  return 0;
}

int run_main_job(const MainJob& c) {
  if (c.out.empty()) {
    std::fprintf(stderr,
                 "obsynth: error: the main job needs an output directory: obsynth %s -o out/\n",
                 c.model.c_str());
    return 1;
  }
  const auto methods = split_list(c.methods);
  RetryState retry;
  // A time or memory stop kills the worker; the retry policy (app/stages.hpp) decides whether
  // to run again without the canonical-form stages or without the design that stopped.
  for (;;) {
    std::optional<JobStop> stop;
    const int code = guarded(
        c.common, [&] { return main_job_body(c, retry.canonical_skipped, retry.excluded); }, &stop);
    if (!stop) return code;
    if (after_stop(methods, stop->stage, stop->reason, retry) == AfterStop::rerun) continue;
    std::fputs(stop->checkpoint.c_str(), stdout);
    std::fflush(stdout);
    print_stop(stop->stage, stop->reason);
    return 1;
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"obsynth: nonlinear observer synthesis from symbolic models"};
  app.set_version_flag("--version", std::string("obsynth ") + OBSYNTH_VERSION);
  app.require_subcommand(0, 1);
  app.footer(
      "Every design option is also accepted as --<design>.<option> (e.g. --canonical.poles), for "
      "that design alone.");
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
  if (job.list_methods) return list_methods(job.list_format);
  if (*check_cmd) return run_check(check);
  if (*sim_cmd) return run_simulate(sim);
  if (!job.model.empty()) return run_main_job(job);
  std::fputs(app.help().c_str(), stdout);
  return 0;
}
