#include "app/synthesize.hpp"

#include <fmt/format.h>

#include <algorithm>

#include "app/report.hpp"
#include "symbolic/expr_print.hpp"

namespace obsynth {

const std::vector<std::string>& all_methods() {
  static const std::vector<std::string> m = {
      "canonical",    "perfect", "riccati", "high-gain",
      "kalman-theta", "thau",    "kou",     "extended-linearization",
      "finite-time"};
  return m;
}

bool is_implemented(const std::string& method) {
  return method == "canonical" || method == "perfect";
}

namespace {

std::string why_not_canonical(const Analysis& a) {
  const auto& cf = a.canonical;
  if (!cf.applicable) return cf.not_applicable;
  std::vector<std::string> f;
  for (const auto& b : cf.drift)
    if (!b.holds()) f.push_back(fmt::format("[tau_{}, tau_{}] != 0", b.i, b.j));
  for (const auto& b : cf.input)
    if (!b.holds()) f.push_back(fmt::format("[g, tau_{}] != 0", b.j));
  if (!f.empty())
    return fmt::format("not linearizable by output injection ({})", fmt::join(f, ", "));
  return cf.l_note;
}

std::string later_methods(const Analysis& a) {
  if (a.observability.generic_rank < a.model.n())
    return "the model is not observable (generic rank " +
           std::to_string(a.observability.generic_rank) +
           " < n): no observer can reconstruct the whole state; reduce the model to its observable "
           "part";
  return "designs for observable models that are not linearizable by output injection — riccati "
         "(James-Baras), high-gain and kalman-theta (Dufour et al.), thau, kou, "
         "extended-linearization, finite-time — are planned for later versions of obsynth";
}

}  // namespace

Synthesis synthesize(const Analysis& a, const SynthesisOptions& opt) {
  Synthesis s;
  std::vector<std::string> methods;
  for (const auto& m : opt.methods) {
    if (m == "auto") {
      const auto& cf = a.canonical;
      if (cf.applicable && cf.linearizable && cf.l_kind == Availability::symbolic) {
        methods.push_back("canonical");
        s.explanation =
            "auto: the bracket conditions hold, so the canonical-form observer applies (its error "
            "dynamics are exactly linear)";
      } else {
        throw UserError(
            SourceLoc{a.model.file, 0, 0},
            fmt::format(
                "no implemented observer design applies to model '{}': canonical form: {}; {}",
                a.model.name, why_not_canonical(a), later_methods(a)));
      }
      continue;
    }
    if (std::find(all_methods().begin(), all_methods().end(), m) == all_methods().end())
      throw UserError(SourceLoc{}, fmt::format("unknown method '{}' (known: auto, {})", m,
                                               fmt::join(all_methods(), ", ")));
    if (!is_implemented(m))
      throw UserError(SourceLoc{}, fmt::format("method '{}' is not implemented in this version of "
                                               "obsynth (implemented: canonical, perfect)",
                                               m));
    if (std::find(methods.begin(), methods.end(), m) == methods.end()) methods.push_back(m);
  }
  std::vector<std::string> summaries;
  for (const auto& m : methods) {
    EmittedHeader h;
    if (m == "canonical") {
      const CanonicalDesign d = design_canonical(a, opt.canonical);
      h = emit_canonical_header(a, d, opt.emit);
    } else {
      const PerfectDesign d = design_perfect(a);
      h = emit_perfect_header(a, d, opt.emit);
    }
    s.files.push_back({h.filename, h.text});
    summaries.push_back(h.summary);
    s.chosen.push_back(m);
  }
  ReportOptions ro;
  ro.timings = false;  // the output directory is byte-identical between runs
  std::string md = render_report(a, ReportFormat::markdown, ro);
  md += "\n## Generated observers\n\n";
  if (!s.explanation.empty()) md += s.explanation + ".\n\n";
  for (const auto& sm : summaries) md += "- " + sm + "\n";
  md += fmt::format(
      "\nLiterals are {} precision; every class is a template on the scalar type (float and "
      "double).\n",
      precision_name(opt.emit.precision));
  auto j = report_json(a, ro);
  j["generated"] = nlohmann::ordered_json::array();
  for (std::size_t i = 0; i < s.chosen.size(); ++i)
    j["generated"].push_back(
        {{"method", s.chosen[i]}, {"file", s.files[i].name}, {"summary", summaries[i]}});
  const std::string stem = cxx_identifier(a.model.name);
  s.files.push_back({stem + "_report.md", md});
  s.files.push_back({stem + "_report.json", j.dump(2) + "\n"});
  return s;
}

}  // namespace obsynth
