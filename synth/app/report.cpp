#include "app/report.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <map>

#include "analysis/conditions.hpp"
#include "designs/registry.hpp"
#include "symbolic/expr_print.hpp"

namespace obsynth {

using nlohmann::ordered_json;

namespace {

std::vector<std::string> names(const std::vector<GiNaC::symbol>& s) {
  std::vector<std::string> out;
  for (const auto& x : s) out.push_back(x.get_name());
  return out;
}

ordered_json expr_list(const ExVec& v) {
  return ordered_json(to_strings(v));
}

ordered_json residual_json(const BracketCheck& b) {
  if (b.residual.empty()) return nullptr;  // too large to print: residual_note says why
  return expr_list(b.residual);
}

std::string residual_text(const BracketCheck& b) {
  return b.residual.empty()
             ? b.residual_note
             : "[" + fmt::format("{}", fmt::join(to_strings(b.residual), ", ")) + "]";
}

ordered_json matrix_json(const ExMatrix& M) {
  ordered_json out = ordered_json::array();
  for (const auto& row : M) out.push_back(expr_list(row));
  return out;
}

std::string vec_text(const ExVec& v) {
  return "[" + fmt::format("{}", fmt::join(to_strings(v), ", ")) + "]";
}

std::string vec_latex(const ExVec& v) {
  std::vector<std::string> parts;
  for (const auto& e : v) parts.push_back(to_latex(e));
  return "\\begin{bmatrix}" + fmt::format("{}", fmt::join(parts, " \\\\ ")) + "\\end{bmatrix}";
}

std::string matrix_latex(const ExMatrix& M) {
  std::vector<std::string> rows;
  for (const auto& r : M) {
    std::vector<std::string> parts;
    for (const auto& e : r) parts.push_back(to_latex(e));
    rows.push_back(fmt::format("{}", fmt::join(parts, " & ")));
  }
  return "\\begin{bmatrix}" + fmt::format("{}", fmt::join(rows, " \\\\ ")) + "\\end{bmatrix}";
}

std::string timings_text(const Analysis& a) {
  std::vector<std::string> t;
  for (const auto& [stage, ms] : a.timings_ms) t.push_back(fmt::format("{} {:.1f} ms", stage, ms));
  return fmt::format("{}", fmt::join(t, ", "));
}

// ": residual [...] (nonzero at x = ...)" for a failing bracket, "" otherwise.
std::string failure_text(const Model& m, const BracketCheck& b) {
  if (b.holds()) return "";
  const std::string at = witness_text(m, b);
  return fmt::format(": residual {}{}", residual_text(b),
                     at.empty() ? "" : fmt::format(" (nonzero at {})", at));
}

// The conclusion of C1-C3: proved, unproven (some bracket only numerically zero), or refuted.
std::string linearizable_text(const CanonicalForm& cf) {
  if (!cf.linearizable) return "NOT linearizable by output injection";
  if (conditions_proved(cf)) return "linearizable by output injection";
  return "linearizability by output injection unproven: a bracket is only numerically zero";
}

// A verdict on T, T^-1 or l(u, y): "proved", "unproven (numerically zero at the sampled
// points)" or "nonzero".
std::string map_verdict_text(ZeroVerdict v) {
  return v == ZeroVerdict::numeric ? "unproven (numerically zero at the sampled points)"
                                   : verdict_name(v);
}

// A bracket's evidence: the points a numeric zero vanished at, a failure's witness point.
void add_evidence_json(const Model& m, const BracketCheck& b, ordered_json& out) {
  if (!b.residual_note.empty()) out["residual_note"] = b.residual_note;
  if (b.verdict == ZeroVerdict::numeric) out["zero_points"] = b.zero_points;
  if (!b.witness.empty()) out["witness"] = witness_text(m, b);
}

std::string rank_method(const Observability& ob) {
  if (ob.jets) return ob.jets->method;
  if (ob.triangular)
    return ob.rank_exact
               ? "O triangular up to a column permutation, its diagonal nonzero: decided exactly"
               : "O triangular up to a column permutation, its diagonal nonzero: decided by the "
                 "zero test";
  return ob.rank_exact ? "exact rational arithmetic at random points"
                       : "60-digit scaled elimination at random points (transcendental entries)";
}

// T^-1 as its elimination sequence: x_state = value (in z and earlier states).
ordered_json inverse_steps_json(const Model& m, const CanonicalForm& cf) {
  if (cf.T_inverse_kind != Availability::symbolic) return nullptr;
  ordered_json steps = ordered_json::array();
  for (const auto& s : cf.T_inverse_steps)
    steps.push_back({{"state", m.states[s.state].get_name()},
                     {"equation", s.equation + 1},
                     {"value", to_string(s.value)}});
  return steps;
}

std::vector<std::string> inverse_steps_text(const Model& m, const CanonicalForm& cf) {
  std::vector<std::string> lines;
  for (const auto& s : cf.T_inverse_steps)
    lines.push_back(fmt::format("{} = {}   (from T_{} = {})", m.states[s.state].get_name(),
                                to_string(s.value), s.equation + 1, cf.z[s.equation].get_name()));
  return lines;
}

std::string inverse_steps_latex(const Model& m, const CanonicalForm& cf) {
  std::vector<std::string> rows;
  for (const auto& s : cf.T_inverse_steps)
    rows.push_back(fmt::format("{} &= {}", to_latex(m.states[s.state]), to_latex(s.value)));
  return "\\begin{aligned}" + fmt::format("{}", fmt::join(rows, " \\\\ ")) + "\\end{aligned}";
}

const char* jets_arithmetic_name(JetsArithmetic a) {
  return a == JetsArithmetic::modular ? "modular" : "ball";
}

ordered_json jets_json(const Observability& ob) {
  const JetsRank& r = *ob.jets;
  const bool modular = r.arithmetic == JetsArithmetic::modular;
  auto only = [](bool when, ordered_json v) { return when ? v : ordered_json(nullptr); };
  return {{"arithmetic", jets_arithmetic_name(r.arithmetic)},
          {"points", r.points},
          {"primes", only(modular, r.primes)},
          {"precision_bits", only(!modular, r.precision_bits)},
          {"rank_with_inputs", r.rank_inputs},
          {"degree_bound", only(modular, r.degree_bound)},
          {"degree_bound_with_inputs", only(modular, r.degree_bound_inputs)},
          {"error_bound", only(modular, r.error_bound)},
          {"error_bound_with_inputs", only(modular, r.error_bound_inputs)},
          {"method", r.method},
          {"symbolic_skipped", ob.symbolic_skipped}};
}

// The symbolic stages a jets rank leaves out, and why.
std::string jets_skipped_text(const Observability& ob) {
  return "not computed: " + ob.symbolic_skipped;
}

std::string jets_inputs_text(const Observability& ob) {
  const JetsRank& r = *ob.jets;
  return fmt::format(
      "rank {} under constant random inputs{}; rank {} of the drift (u = 0) is the rank of O",
      r.rank_inputs,
      r.arithmetic == JetsArithmetic::modular && r.rank_inputs < r.n
          ? fmt::format(" (P(under-estimated) <= {:.2g})", r.error_bound_inputs)
          : std::string(),
      r.rank);
}

std::string lie_name(std::size_t k, std::size_t i, std::size_t p) {
  const std::string h = p == 1 ? "h" : fmt::format("h{}", i + 1);
  return k == 0 ? h : (k == 1 ? fmt::format("L_f {}", h) : fmt::format("L_f^{} {}", k, h));
}

// Partial reports. Each renderer marks where a stage's section begins; a report is cut at the
// first section whose stage a budget stop lost (its data is then empty), and the stage
// statuses follow.
class SectionMarks {
 public:
  explicit SectionMarks(const std::string& text) : text_(text) {}
  void mark(const std::string& stage) { at_.emplace(stage, text_.size()); }
  std::size_t cut_position(const Analysis& a) const {
    std::size_t pos = text_.size();
    for (const auto& [stage, at] : at_)
      if (a.lost(stage)) pos = std::min(pos, at);
    return pos;
  }

 private:
  const std::string& text_;
  std::map<std::string, std::size_t> at_;
};

std::string stage_line(const StageOutcome& s) {
  return s.reason.empty()
             ? fmt::format("{}: {}", s.name, stage_status_name(s.status))
             : fmt::format("{}: {}: {}", s.name, stage_status_name(s.status), s.reason);
}

std::string incomplete_text(const Analysis& a) {
  if (a.complete()) return {};
  std::string s = "\nReport incomplete: a budget stopped the analysis\n";
  for (const auto& st : a.stages) s += "  " + stage_line(st) + "\n";
  return s;
}

std::string incomplete_markdown(const Analysis& a) {
  if (a.complete()) return {};
  std::string s = "\n## Report incomplete\n\nA budget stopped the analysis.\n\n";
  s += "| stage | status | reason |\n|---|---|---|\n";
  for (const auto& st : a.stages)
    s += fmt::format("| {} | {} | {} |\n", st.name, stage_status_name(st.status), st.reason);
  return s;
}

std::string incomplete_latex(const Analysis& a) {
  if (a.complete()) return {};
  std::string s = "\\paragraph{Report incomplete.} A budget stopped the analysis.\n";
  s += "\\begin{itemize}\n";
  for (const auto& st : a.stages)
    s += fmt::format("  \\item \\texttt{{{}}}: {}{}\n", latex_text(st.name),
                     stage_status_name(st.status),
                     st.reason.empty() ? "" : ": \\texttt{" + latex_text(st.reason) + "}");
  return s + "\\end{itemize}\n";
}

// JSON keys holding each stage's results: null when a budget stop lost the stage.
const std::vector<std::pair<const char*, std::vector<const char*>>>& stage_json_keys() {
  static const std::vector<std::pair<const char*, std::vector<const char*>>> keys = {
      {"lie", {"lie_derivatives"}},
      {"observability", {"observability"}},
      {"frame", {"canonical_applicable", "canonical_note", "r", "frame"}},
      {"conditions", {"conditions", "linearizable"}},
      {"diffeomorphism",
       {"base_point", "T", "T_info", "T_inverse", "T_inverse_info", "l", "l_info"}}};
  return keys;
}

}  // namespace

std::string latex_text(const std::string& t) {
  std::string e;
  for (char c : t) {
    if (std::string("_%&#${}").find(c) != std::string::npos)
      e += std::string("\\") + c;
    else if (c == '~' || c == '^' || c == '\\')
      e += fmt::format("\\char{}{{}}", static_cast<int>(c));
    else
      e += c;
  }
  return e;
}

// Observability under inputs (issue 8): JSON and report lines.
ordered_json triangular_json(const TriangularForm& t) {
  return {{"convention",
           "output first: z' = A(u) z + phi(u, z), y = z1, a_i(u) on the "
           "superdiagonal (seed 002 eq. 1-2)"},
          {"coordinates", coordinates_name(t.coordinates)},
          {"z_of_x", expr_list(t.z_of_x)},
          {"a", expr_list(t.a)},
          {"phi", expr_list(t.phi)}};
}

const char* tri_state(const std::optional<bool>& b) {
  return !b ? "undecided" : *b ? "true" : "false";
}

ordered_json under_inputs_json(const Analysis& a) {
  const ObservabilityUnderInputs& u = a.under_inputs;
  ordered_json j;
  auto opt_bool = [](const std::optional<bool>& b) {
    return b ? ordered_json(*b) : ordered_json(nullptr);
  };
  j["computed"] = u.computed;
  j["generic_rank"] = u.computed ? ordered_json(u.generic_rank) : ordered_json(nullptr);
  j["rank_method"] = u.computed ? ordered_json(u.rank_method) : ordered_json(nullptr);
  j["det"] = u.det ? ordered_json(to_string(*u.det)) : ordered_json(nullptr);
  ordered_json sing = ordered_json::array(), in_box = ordered_json::array();
  for (const auto& s : u.singular) {
    sing.push_back(to_string(s.factor));
    in_box.push_back(
        {{"factor", to_string(s.factor)},
         {"vanishes_in_box", s.in_box.kind == BoxZeros::somewhere ? ordered_json(true)
                             : s.in_box.kind == BoxZeros::never   ? ordered_json(false)
                                                                  : ordered_json(nullptr)},
         {"detail", s.in_box.detail}});
  }
  j["singular_inputs"] = sing;
  j["singular_inputs_in_box"] = in_box;
  j["rank_drop"] = expr_list(u.rank_drop);
  j["observation_space_rank"] =
      u.observation_space_rank ? ordered_json(*u.observation_space_rank) : ordered_json(nullptr);
  j["observable_for_some_input"] = opt_bool(u.observable_for_some_input);
  j["uniformly_observable"] = opt_bool(u.uniformly_observable);
  j["reason"] = u.reason;
  j["triangular_form"] = u.triangular ? triangular_json(*u.triangular) : ordered_json(nullptr);
  j["triangular_note"] = u.triangular_note;
  return j;
}

std::vector<std::string> under_inputs_lines(const Analysis& a) {
  const ObservabilityUnderInputs& u = a.under_inputs;
  std::vector<std::string> out;
  if (!a.model.nominal_note.empty()) out.push_back(a.model.nominal_note);
  if (a.model.feedthrough())
    out.push_back(
        "the output depends on the input (direct feedthrough): the drift rank above "
        "reads h at the nominal input");
  if (!u.computed) {
    out.push_back(u.reason.empty() ? "not computed" : u.reason);
    return out;
  }
  out.push_back(
      fmt::format("generic rank of O_u (rows dL_{{f+g(.,u)}}^k h, inputs as constants): "
                  "{} of n = {} ({})",
                  u.generic_rank, u.n, u.rank_method));
  if (u.det) out.push_back(fmt::format("det O_u = {}", to_string(*u.det)));
  if (u.generic_rank == u.n) {
    if (u.singular.empty()) {
      out.push_back(u.det ? "singular inputs: none" : "singular inputs: not computed");
    }
    for (const auto& s : u.singular)
      out.push_back(fmt::format(
          "singular input: {} = 0; {}", to_string(s.factor),
          s.in_box.kind == BoxZeros::never       ? std::string("never on the input box (proved)")
          : s.in_box.kind == BoxZeros::somewhere ? "in the input box: " + s.in_box.detail
                                                 : s.in_box.detail));
  }
  if (u.observation_space_rank && u.generic_rank < u.n)
    out.push_back(
        fmt::format("observation space rank (all input sequences): {}", *u.observation_space_rank));
  if (u.triangular) {
    const TriangularForm& t = *u.triangular;
    out.push_back(fmt::format(
        "triangular form (seed 002, output first) in the {}: z = [{}], a(u) = [{}], phi = [{}]",
        t.coordinates == TriangularForm::Coordinates::states ? "states"
                                                             : "coordinates (h, L_f h, ...)",
        fmt::join(to_strings(t.z_of_x), ", "), fmt::join(to_strings(t.a), ", "),
        fmt::join(to_strings(t.phi), ", ")));
  }
  out.push_back(
      fmt::format("uniformly observable: {}; {}", tri_state(u.uniformly_observable), u.reason));
  if (u.observable_for_some_input == true && a.observability.generic_rank < a.model.n())
    out.push_back(std::string("designs that work under persistent inputs: ") +
                  persistent_input_designs(u));
  return out;
}

// The drift rank's deficit line: "NOT observable" only when no input helps.
std::string drift_deficit_text(const Analysis& a) {
  const Observability& ob = a.observability;
  const ObservabilityUnderInputs& u = a.under_inputs;
  if (u.computed && u.observable_for_some_input == true)
    return fmt::format(
        "rank deficit {} for the drift alone (inputs at {}); observable under "
        "inputs (see below)",
        ob.n - ob.generic_rank, a.model.nominal.empty() ? "0" : "u0");
  if (u.computed && u.observable_for_some_input == false)
    return fmt::format("NOT observable: rank deficit {} everywhere, for every input",
                       ob.n - ob.generic_rank);
  if (a.model.m() == 0)
    return fmt::format("NOT observable: rank deficit {} everywhere", ob.n - ob.generic_rank);
  return fmt::format("rank deficit {} for the drift alone; under inputs: {}",
                     ob.n - ob.generic_rank, u.reason.empty() ? "undecided" : u.reason);
}

namespace {

// The model: schema, name, symbols, parameters and the maps.
const char* defined_status_name(certify::DefinedStatus s) {
  switch (s) {
    case certify::DefinedStatus::violated_everywhere:
      return "fails everywhere";
    case certify::DefinedStatus::violated_somewhere:
      return "fails somewhere";
    case certify::DefinedStatus::not_excluded:
      break;
  }
  return "not proved";
}

// Where f + g and h are defined on the box: the conditions checked and those not proved.
ordered_json definedness_json(const certify::Definedness& d) {
  ordered_json findings = ordered_json::array();
  for (const auto& f : d.findings)
    findings.push_back({{"component", f.component},
                        {"requirement", f.requirement},
                        {"status", defined_status_name(f.status)},
                        {"where", f.sub_box},
                        {"witness", f.witness}});
  return {{"conditions", d.conditions},
          {"defined_on_box", d.findings.empty()},
          {"findings", findings},
          {"summary", d.summary()}};
}

void add_model_json(const Analysis& a, ordered_json& j) {
  const Model& m = a.model;
  // Schema 2: T_inverse is a list of elimination steps {state, equation (1-based), value}
  // (schema 1, without this key, had T_inverse as a list of expressions in z).
  j["schema"] = 2;
  j["model"] = m.name;
  j["complete"] = a.complete();
  j["states"] = names(m.states);
  j["inputs"] = names(m.inputs);
  ordered_json params = ordered_json::array();
  for (const auto& p : m.params)
    params.push_back(
        {{"name", p.name},
         {"value", p.value ? ordered_json(to_string(*p.value)) : ordered_json(nullptr)}});
  j["params"] = params;
  j["f"] = expr_list(m.f);
  j["g"] = expr_list(m.g);
  j["h"] = expr_list(m.h);
  j["definedness"] = definedness_json(a.definedness);
}

// The "observability" object: rank, its method, O, indices, det and the rank drop.
ordered_json observability_json(const Analysis& a) {
  const Observability& ob = a.observability;
  ordered_json o;
  o["n"] = ob.n;
  o["p"] = ob.p;
  o["generic_rank"] = ob.generic_rank;
  o["rank_method"] = ob.jets         ? "jets"
                     : ob.triangular ? "triangular"
                     : ob.rank_exact ? "exact"
                                     : "high-precision";
  if (ob.jets) o["jets"] = jets_json(ob);
  o["matrix"] = ob.jets ? ordered_json(nullptr) : matrix_json(ob.O);
  o["indices"] = ob.indices;
  o["det"] = ob.generic_rank == ob.n && ob.selected.size() == ob.n ? ordered_json(to_string(ob.det))
                                                                   : ordered_json(nullptr);
  o["rank_drop"] = ob.jets ? ordered_json(nullptr) : expr_list(ob.rank_drop);
  o["undefined"] = ob.jets ? ordered_json(nullptr) : expr_list(ob.undefined);
  o["under_inputs"] = under_inputs_json(a);
  return o;
}

// The "conditions" object: the drift and input bracket conditions and completeness.
ordered_json conditions_json(const Analysis& a) {
  const CanonicalForm& cf = a.canonical;
  ordered_json c;
  // One list: each check's indices (`head`), then name, verdict, residual and evidence.
  auto list = [&](const std::vector<BracketCheck>& checks, auto head, auto name) {
    ordered_json out = ordered_json::array();
    for (const auto& b : checks) {
      ordered_json e = head(b);
      e["name"] = name(cf, b);
      e["holds"] = b.holds();
      e["verdict"] = verdict_name(b.verdict);
      e["residual"] = residual_json(b);
      add_evidence_json(a.model, b, e);
      out.push_back(std::move(e));
    }
    return out;
  };
  const ordered_json drift = list(
      cf.drift,
      [](const BracketCheck& b) {
        return ordered_json{{"i", b.i}, {"j", b.j}};
      },
      drift_condition_name);
  const ordered_json input = list(
      cf.input,
      [](const BracketCheck& b) {
        return ordered_json{{"j", b.j}};
      },
      input_condition_name);
  const ordered_json output = list(
      cf.output,
      [](const BracketCheck& b) {
        return ordered_json{{"output", b.i}, {"j", b.j}};
      },
      output_condition_name);
  c["observable"] = a.observability.generic_rank == a.observability.n;
  c["drift"] = drift;
  c["input"] = input;
  c["output"] = output;
  c["complete"] =
      cf.applicable ? ordered_json(completeness_name(cf.complete)) : ordered_json(nullptr);
  c["complete_reason"] = cf.complete_reason;
  return c;
}

// The canonical form: r, frame, conditions, T, T^-1 and l with their kinds and verdicts.
void add_canonical_json(const Analysis& a, ordered_json& j) {
  const CanonicalForm& cf = a.canonical;
  const bool app = cf.applicable;
  j["canonical_applicable"] = app;
  j["canonical_note"] = cf.not_applicable;
  j["r"] = app ? expr_list(cf.r) : ordered_json(nullptr);
  j["blocks"] = cf.blocks;
  j["frame_note"] = cf.frame_note;
  if (const auto& t = a.output_transformation)
    j["output_transformation"] = {{"psi", expr_list(t->psi)},
                                  {"y",
                                   [&] {
                                     std::vector<std::string> names;
                                     for (const auto& y : t->y) names.push_back(y.get_name());
                                     return names;
                                   }()},
                                  {"observed_h", expr_list(t->observed.h)},
                                  {"failing_for_y",
                                   [&] {
                                     ordered_json list = ordered_json::array();
                                     for (const auto& [name, b] : t->failing_checks)
                                       list.push_back({{"condition", name},
                                                       {"residual", expr_list(b.residual)},
                                                       {"residual_note", b.residual_note}});
                                     return list;
                                   }()},
                                  {"how", t->how}};
  else
    j["output_transformation"] = nullptr;
  j["output_transformation_note"] = a.output_transformation_note;
  if (app) {
    ordered_json fr = ordered_json::array();
    for (const auto& t : cf.frame) fr.push_back(expr_list(t));
    j["frame"] = fr;
  } else {
    j["frame"] = nullptr;
  }
  j["conditions"] = conditions_json(a);
  // Only a proof concludes; numerically zero brackets leave linearizability unproven.
  j["linearizable"] = app && cf.linearizable && conditions_proved(cf);
  j["linearizability"] = !app                    ? ordered_json(nullptr)
                         : !cf.linearizable      ? ordered_json("refuted")
                         : conditions_proved(cf) ? ordered_json("proved")
                                                 : ordered_json("unproven");
  j["base_point"] = cf.base_point.empty() ? ordered_json(nullptr) : expr_list(cf.base_point);
  auto map_entry = [&](const char* key, Availability kind, const ExVec& v, ZeroVerdict verdict,
                       const std::string& note) {
    j[key] = kind == Availability::symbolic ? expr_list(v) : ordered_json(nullptr);
    j[std::string(key) + "_info"] = {
        {"kind", availability_name(kind)},
        {"verdict", kind == Availability::symbolic ? ordered_json(verdict_name(verdict))
                                                   : ordered_json(nullptr)},
        {"note", note}};
  };
  map_entry("T", cf.T_kind, cf.T, cf.T_verdict, cf.T_note);
  map_entry("T_inverse", cf.T_inverse_kind, {}, cf.T_inverse_verdict, cf.T_inverse_note);
  j["T_inverse"] = inverse_steps_json(a.model, cf);
  map_entry("l", cf.l_kind, cf.l, cf.l_verdict, cf.l_note);
}

}  // namespace

ordered_json report_json(const Analysis& a, const ReportOptions& opt) {
  const Model& m = a.model;
  const Observability& ob = a.observability;
  ordered_json j;
  add_model_json(a, j);
  if (ob.jets || ob.lie.empty()) {  // empty: a progress report before the chain completed
    j["lie_derivatives"] = nullptr;
  } else if (ob.p == 1) {
    j["lie_derivatives"] = expr_list(ob.lie[0]);
  } else {
    ordered_json l = ordered_json::array();
    for (const auto& v : ob.lie) l.push_back(expr_list(v));
    j["lie_derivatives"] = l;
  }
  j["observability"] = observability_json(a);
  if (!m.nominal_note.empty()) {
    ordered_json nom = ordered_json::object();
    for (std::size_t i = 0; i < m.inputs.size(); ++i)
      nom[m.inputs[i].get_name()] = to_string(i < m.nominal.size() ? m.nominal[i] : 0);
    j["nominal_input"] = {{"values", nom}, {"note", m.nominal_note}};
  }
  // y depends on u: either not separably (feedthrough()), or as h0(x) + k(u), whose k(u) every
  // design subtracts (output_offset, the analysis observes y - k(u) = h0(x)).
  if (m.feedthrough() || !m.output_offset.empty()) j["feedthrough"] = true;
  if (!m.output_offset.empty()) {
    ordered_json k = ordered_json::array();
    for (const auto& e : m.output_offset) k.push_back(to_string(e));
    j["output_offset"] = k;
  }
  add_canonical_json(a, j);
  ordered_json t = ordered_json::object();
  for (const auto& [stage, ms] : a.timings_ms) t[stage] = opt.timings ? ms : 0.0;
  j["timings_ms"] = t;
  ordered_json stages = ordered_json::array();
  for (const auto& st : a.stages)
    stages.push_back(
        {{"name", st.name}, {"status", stage_status_name(st.status)}, {"reason", st.reason}});
  j["stages"] = stages;
  // A stage that did not complete: its keys are null, not half-built.
  for (const auto& [stage, keys] : stage_json_keys())
    if (a.lost(stage))
      for (const char* key : keys)
        if (j.contains(key)) j[key] = nullptr;
  return j;
}

namespace {

// Appends a line to the text.
struct LineWriter {
  std::string& s;
  void operator()(const std::string& t) const { s += t + "\n"; }
};

// Where O loses rank: the zeros of det O (one output). With several outputs det is the
// selected rows' minor: where it vanishes, O's other rows (L_f^k h_i, k >= k_i) may keep the
// rank, which is not checked, so the set only bounds where the rank may drop.
std::string rank_drop_text(const Observability& ob) {
  if (ob.rank_drop.empty()) return "the rank never drops";
  const std::string factors = fmt::format("{}", fmt::join(to_strings(ob.rank_drop), "; "));
  if (ob.p == 1) return "the rank drops where any of these vanish: " + factors;
  return "the selected rows lose rank where any of these vanish: " + factors +
         " (O's other rows may keep the rank there: not checked, so the rank may drop only "
         "there)";
}

// The observability section of the text report: Lie derivatives, O, its rank, det O, and
// observability under inputs.
void text_observability(const Analysis& a, SectionMarks& marks, const LineWriter& line) {
  const Observability& ob = a.observability;
  marks.mark("lie");
  line("");
  line("Lie derivatives");
  if (ob.jets) line("  " + jets_skipped_text(ob));
  for (std::size_t i = 0; i < ob.lie.size(); ++i)
    for (std::size_t k = 0; k < ob.lie[i].size(); ++k)
      line(fmt::format("  {} = {}", lie_name(k, i, ob.p), to_string(ob.lie[i][k])));
  marks.mark("observability");
  line("");
  line("Observability");
  for (std::size_t r = 0; r < ob.O.size(); ++r)
    line(fmt::format("  d({}) = {}", lie_name(ob.rows[r].order, ob.rows[r].output, ob.p),
                     vec_text(ob.O[r])));
  line(fmt::format("  generic rank {} of n = {}  ({})", ob.generic_rank, ob.n, rank_method(ob)));
  if (ob.p > 1) line(fmt::format("  observability indices {}", fmt::join(ob.indices, ", ")));
  if (ob.jets) {
    line("  " + jets_inputs_text(ob));
    if (ob.generic_rank < ob.n) line("  " + drift_deficit_text(a));
    line("  det O and the rank-drop set: not computed (they need the symbolic O)");
  } else if (ob.generic_rank == ob.n) {
    line(fmt::format("  det O{} = {}", ob.p > 1 ? " (selected rows)" : "", to_string(ob.det)));
    line("  " + rank_drop_text(ob));
  } else {
    line("  " + drift_deficit_text(a));
  }
  if (!ob.undefined.empty())
    line(fmt::format("  O is undefined where any of these vanish: {}",
                     fmt::join(to_strings(ob.undefined), "; ")));
  line("");
  line("Observability under inputs");
  for (const auto& t : under_inputs_lines(a)) line("  " + t);
}

// The diffeomorphism T, its inverse and the canonical form (a linearizable model).
void text_diffeomorphism(const Analysis& a, SectionMarks& marks, const LineWriter& line) {
  const Model& m = a.model;
  const CanonicalForm& cf = a.canonical;
  marks.mark("diffeomorphism");
  line("");
  line(fmt::format("Diffeomorphism z = T(x), T(x0) = 0 at x0 = {}", vec_text(cf.base_point)));
  if (cf.T_kind == Availability::symbolic) line(fmt::format("  T = {}", vec_text(cf.T)));
  line(fmt::format("  T: {} ({})", availability_name(cf.T_kind), cf.T_note));
  if (cf.T_inverse_kind == Availability::symbolic) {
    line("  T^-1, in this order:");
    for (const auto& t : inverse_steps_text(m, cf)) line("    " + t);
  }
  line(fmt::format("  T^-1: {} ({})", availability_name(cf.T_inverse_kind), cf.T_inverse_note));
  if (cf.l_kind == Availability::symbolic) {
    line("");
    line("Canonical form (output last)");
    for (std::size_t i = 0; i < cf.l.size(); ++i)
      line(fmt::format("  {}' = {}{}", cf.z[i].get_name(),
                       i == cf.block_start(cf.block_of(i)) ? "" : cf.z[i - 1].get_name() + " + ",
                       to_string(cf.l[i])));
    for (std::size_t q = 0; q < cf.outputs(); ++q)
      line(fmt::format("  {} = {}{}", cf.y[q].get_name(), cf.z_name(cf.block_end(q)),
                       cf.base_point.empty() ? ""
                       : cf.outputs() == 1   ? " + h(x0)"
                                             : fmt::format(" + h{}(x0)", q + 1)));
    line(fmt::format("  l(u, y) free of x: {}", map_verdict_text(cf.l_verdict)));
  } else {
    line(fmt::format("  l: {}", cf.l_note));
  }
}

// The output transformation found (the form that follows is for psi(y)), or why none was.
std::string output_transformation_text(const Analysis& a) {
  if (const auto& t = a.output_transformation)
    return fmt::format(
        "output transformation y~ = psi(y) = [{}] (Krener-Respondek): the conditions fail for y "
        "itself ({}); {}. Everything below is for the model observed through psi, h~ = psi(h) = "
        "[{}], and y in l(u, y) stands for psi(y)",
        fmt::join(to_strings(t->psi), ", "), t->failing, t->how,
        fmt::join(to_strings(t->observed.h), ", "));
  if (!a.output_transformation_note.empty()) return a.output_transformation_note;
  return "";
}

// The linearization section: r, the frame, conditions C1-C4 and, if linearizable, T.
void text_canonical(const Analysis& a, SectionMarks& marks, const LineWriter& line) {
  const CanonicalForm& cf = a.canonical;
  marks.mark("frame");
  line("");
  line("Linearization by output injection (observer canonical form)");
  if (const std::string t = output_transformation_text(a); !t.empty()) line("  " + t);
  if (a.output_transformation)
    for (const auto& [name, b] : a.output_transformation->failing_checks)
      line(fmt::format("  in y itself: {} = 0 FAILS{}", name, failure_text(a.model, b)));
  if (!cf.applicable) {
    line("  " + cf.not_applicable);
  } else {
    if (!cf.r.empty()) line(fmt::format("  r = {}", vec_text(cf.r)));
    if (cf.outputs() > 1)
      line(fmt::format(
          "  blocks k = ({}), the observability indices; r_i = tau_{{i,1}} solves "
          "O r_i = e_(i, k_i - 1){}",
          fmt::join(cf.blocks, ", "), cf.frame_note.empty() ? "" : "\n  note: " + cf.frame_note));
    for (std::size_t k = 0; k < cf.frame.size(); ++k)
      line(fmt::format("  {} = {}", cf.tau_name(k), vec_text(cf.frame[k])));
    marks.mark("conditions");
    auto condition = [&](const std::string& name, const BracketCheck& b) {
      line(fmt::format("  {:<30}{}{}", name.size() < 30 ? name : name + " ",
                       bracket_verdict_text(b), failure_text(a.model, b)));
    };
    line(fmt::format("  C1 rank O = n                 holds"));
    for (const auto& b : cf.drift) condition("C2 " + drift_condition_name(cf, b), b);
    for (const auto& b : cf.input) condition("C3 " + input_condition_name(cf, b), b);
    for (const auto& b : cf.output) condition("C5 " + output_condition_name(cf, b), b);
    line(fmt::format("  C4 completeness               {}: {}", completeness_name(cf.complete),
                     cf.complete_reason));
    line("  => " + linearizable_text(cf));
    if (cf.linearizable) text_diffeomorphism(a, marks, line);
  }
}

std::string render_text(const Analysis& a, const ReportOptions& opt) {
  const Model& m = a.model;
  std::string s;
  SectionMarks marks(s);
  const LineWriter line{s};
  line(fmt::format("model {}  (n = {} states: {}; m = {} inputs{}{}; p = {} output{})", m.name,
                   m.n(), fmt::join(names(m.states), ", "), m.m(), m.m() ? ": " : "",
                   fmt::join(names(m.inputs), ", "), m.p(), m.p() == 1 ? "" : "s"));
  line(fmt::format("  f = {}", vec_text(m.f)));
  line(fmt::format("  g = {}", vec_text(m.g)));
  line(fmt::format("  h = {}", vec_text(m.h)));
  line("  definedness: " + a.definedness.summary());
  text_observability(a, marks, line);
  text_canonical(a, marks, line);
  s.resize(marks.cut_position(a));
  s += incomplete_text(a);
  if (opt.timings) {
    line("");
    line("timings: " + timings_text(a));
  }
  return s;
}

// The observability section of the Markdown report: Lie derivatives, O, its rank, det O,
// and observability under inputs.
void markdown_observability(const Analysis& a, SectionMarks& marks, const LineWriter& line) {
  const Observability& ob = a.observability;
  marks.mark("lie");
  line("## Observability");
  line("");
  if (ob.jets)
    line("Lie derivatives, $O$, $\\det O$ and the rank-drop set: " + jets_skipped_text(ob) + ".");
  if (!ob.jets) line("| Lie derivative | expression |");
  if (!ob.jets) line("|---|---|");
  for (std::size_t i = 0; i < ob.lie.size(); ++i)
    for (std::size_t k = 0; k < ob.lie[i].size(); ++k)
      line(fmt::format(
          "| ${}$ | ${}$ |",
          k == 0 ? (ob.p == 1 ? std::string("h") : fmt::format("h_{}", i + 1))
                 : fmt::format("L_f^{{{}}} h{}", k, ob.p == 1 ? "" : fmt::format("_{}", i + 1)),
          to_latex(ob.lie[i][k])));
  line("");
  marks.mark("observability");
  if (!ob.jets) line(fmt::format("$$O(x) = {}$$", matrix_latex(ob.O)));
  line("");
  line(fmt::format("- generic rank **{}** of $n = {}$ ({})", ob.generic_rank, ob.n,
                   rank_method(ob)));
  if (ob.jets) line("- " + jets_inputs_text(ob));
  if (!ob.jets && ob.generic_rank == ob.n) {
    line(fmt::format("- $\\det O = {}$", to_latex(ob.det)));
    if (ob.rank_drop.empty() || ob.p > 1) line("- " + rank_drop_text(ob));
    if (ob.p == 1)
      for (const auto& f : ob.rank_drop) line(fmt::format("- rank drops on ${} = 0$", to_latex(f)));
  }
  for (const auto& f : ob.undefined) line(fmt::format("- $O$ undefined on ${} = 0$", to_latex(f)));
  if (ob.generic_rank < ob.n) line("- " + drift_deficit_text(a));
  line("");
  line("### Observability under inputs");
  line("");
  for (const auto& t : under_inputs_lines(a)) line("- " + t);
  line("");
}

// The table of conditions C1-C4.
void markdown_conditions(const Analysis& a, SectionMarks& marks, const LineWriter& line) {
  const CanonicalForm& cf = a.canonical;
  marks.mark("conditions");
  line("| condition | verdict | residual |");
  line("|---|---|---|");
  line("| C1: rank $O = n$ | holds | |");
  auto row = [&](const std::string& name, const BracketCheck& b) {
    line(fmt::format(
        "| {}: ${}$ | {} | {} |", name.substr(0, 2), name.substr(3), bracket_verdict_text(b),
        b.holds() ? ""
                  : (b.residual.empty() ? b.residual_note : "$" + vec_latex(b.residual) + "$")));
  };
  auto tex = [](std::string s) {  // tau_3 -> \tau_{3}, tau_{2,1} -> \tau_{2,1}, <> -> langle
    std::string out;
    for (std::size_t i = 0; i < s.size(); ++i) {
      if (s.compare(i, 4, "tau_") == 0) {
        out += "\\tau_";
        i += 3;
        if (i + 1 < s.size() && s[i + 1] != '{') {
          std::size_t e = i + 1;
          while (e < s.size() && std::isdigit(static_cast<unsigned char>(s[e]))) ++e;
          out += "{" + s.substr(i + 1, e - i - 1) + "}";
          i = e - 1;
        }
      } else if (s[i] == '<') {
        out += "\\langle ";
      } else if (s[i] == '>') {
        out += " \\rangle";
      } else {
        out += s[i];
      }
    }
    return out;
  };
  for (const auto& b : cf.drift) row("C2 " + tex(drift_condition_name(cf, b)), b);
  for (const auto& b : cf.input) row("C3 " + tex(input_condition_name(cf, b)), b);
  for (const auto& b : cf.output) row("C5 " + tex(output_condition_name(cf, b)), b);
  line(fmt::format("| C4: completeness | {} | {} |", completeness_name(cf.complete),
                   cf.complete_reason));
}

// The linearization section: r, the conditions and, if available, T, T^-1 and l.
void markdown_canonical(const Analysis& a, SectionMarks& marks, const LineWriter& line) {
  const Model& m = a.model;
  const CanonicalForm& cf = a.canonical;
  marks.mark("frame");
  line("## Linearization by output injection");
  line("");
  if (const std::string t = output_transformation_text(a); !t.empty()) {
    line(t + ".");
    line("");
  }
  if (a.output_transformation) {
    for (const auto& [name, b] : a.output_transformation->failing_checks)
      line(fmt::format("- in y itself: {} = 0 fails{}", name, failure_text(a.model, b)));
    if (!a.output_transformation->failing_checks.empty()) line("");
  }
  if (!cf.applicable) {
    line(cf.not_applicable);
  } else {
    line(fmt::format("$$r = {}$$", vec_latex(cf.r)));
    line("");
    markdown_conditions(a, marks, line);
    line("");
    line("**" + linearizable_text(cf) + ".**");
    marks.mark("diffeomorphism");
    if (cf.T_kind == Availability::symbolic) {
      line("");
      line(fmt::format("$$T(x) = {}, \\qquad T^{{-1}}(z) = {}$$", vec_latex(cf.T),
                       cf.T_inverse_kind == Availability::symbolic
                           ? inverse_steps_latex(m, cf)
                           : std::string("\\text{(Newton)}")));
    }
    if (cf.l_kind == Availability::symbolic) {
      line("");
      line(fmt::format("Canonical form $\\dot z = A z + l(u, y)$, $y = z_{}$ with $$l(u,y) = {}$$",
                       cf.l.size(), vec_latex(cf.l)));
    }
  }
}

std::string render_markdown(const Analysis& a, const ReportOptions& opt) {
  const Model& m = a.model;
  std::string s;
  SectionMarks marks(s);
  const LineWriter line{s};
  line(fmt::format("# Observer analysis: `{}`", m.name));
  line("");
  line(fmt::format("States $x = ({})$, inputs $({})$, {} output{}.",
                   fmt::join(names(m.states), ", "), fmt::join(names(m.inputs), ", "), m.p(),
                   m.p() == 1 ? "" : "s"));
  line("");
  line(fmt::format("$$f = {}, \\quad g = {}, \\quad h = {}$$", vec_latex(m.f), vec_latex(m.g),
                   vec_latex(m.h)));
  line("");
  line("Definedness: " + a.definedness.summary() + ".");
  line("");
  markdown_observability(a, marks, line);
  markdown_canonical(a, marks, line);
  s.resize(marks.cut_position(a));
  s += incomplete_markdown(a);
  if (opt.timings) {
    line("");
    line("_Timings: " + timings_text(a) + "._");
  }
  return s;
}

std::string render_latex(const Analysis& a) {
  const Model& m = a.model;
  const Observability& ob = a.observability;
  const CanonicalForm& cf = a.canonical;
  std::string s;
  SectionMarks marks(s);
  auto line = [&](const std::string& t) { s += t + "\n"; };
  line(fmt::format("% obsynth analysis of model {} (needs amsmath)", m.name));
  line(fmt::format("\\subsection*{{Observer analysis of \\texttt{{{}}}}}", [&] {
    std::string e;
    for (char c : m.name) e += c == '_' ? std::string("\\_") : std::string(1, c);
    return e;
  }()));
  marks.mark("lie");  // O shares its environment with f, g, h
  marks.mark("observability");
  line("\\begin{align*}");
  line(fmt::format("  f(x) &= {}, & g(x,u) &= {}, & h(x) &= {} \\\\", vec_latex(m.f),
                   vec_latex(m.g), vec_latex(m.h)));
  if (ob.jets)
    line(fmt::format("  \\operatorname{{rank}} O &= {} & &\\text{{({})}}", ob.generic_rank,
                     rank_method(ob)));
  else
    line(fmt::format("  O(x) &= {}, & \\operatorname{{rank}} O &= {}", matrix_latex(ob.O),
                     ob.generic_rank));
  if (!ob.jets && ob.generic_rank == ob.n)
    line(fmt::format("  , & \\det O &= {}", to_latex(ob.det)));
  line("\\end{align*}");
  line("\\paragraph{Observability under inputs}");
  line("\\begin{itemize}");
  if (ob.generic_rank < ob.n) line("  \\item " + latex_text(drift_deficit_text(a)));
  for (const auto& t : under_inputs_lines(a)) line("  \\item " + latex_text(t));
  line("\\end{itemize}");
  marks.mark("frame");
  if (cf.applicable) {
    line("\\begin{align*}");
    line(fmt::format("  r &= {}", vec_latex(cf.r)));
    for (std::size_t k = 1; k < cf.frame.size(); ++k)
      line(fmt::format("  \\\\ \\tau_{{{}}} &= {}", k + 1, vec_latex(cf.frame[k])));
    line("\\end{align*}");
    marks.mark("conditions");
    line("\\begin{itemize}");
    for (const auto& b : cf.drift)
      line(fmt::format("  \\item $[\\tau_{{{}}}, \\tau_{{{}}}] {}$ ({})", b.i, b.j,
                       b.holds() ? "= 0"
                                 : (b.residual.empty() ? std::string("\\neq 0")
                                                       : "= " + vec_latex(b.residual) + " \\neq 0"),
                       latex_text(bracket_verdict_text(b))));
    for (const auto& b : cf.input)
      line(fmt::format("  \\item $[g, \\tau_{{{}}}] {}$ ({})", b.j,
                       b.holds() ? "= 0"
                                 : (b.residual.empty() ? std::string("\\neq 0")
                                                       : "= " + vec_latex(b.residual) + " \\neq 0"),
                       latex_text(bracket_verdict_text(b))));
    line(fmt::format("  \\item completeness: {}", completeness_name(cf.complete)));
    line("\\end{itemize}");
    marks.mark("diffeomorphism");
    if (cf.T_kind == Availability::symbolic && cf.l_kind == Availability::symbolic) {
      line("\\begin{align*}");
      line(fmt::format("  T(x) &= {}, & l(u,y) &= {}", vec_latex(cf.T), vec_latex(cf.l)));
      if (cf.T_inverse_kind == Availability::symbolic)
        line(fmt::format("  \\\\ T^{{-1}}(z) &= {}", inverse_steps_latex(m, cf)));
      line("\\end{align*}");
    }
  } else {
    line(cf.not_applicable);
  }
  s.resize(marks.cut_position(a));
  s += incomplete_latex(a);
  return s;
}

}  // namespace

std::string render_report(const Analysis& a, ReportFormat format, const ReportOptions& opt) {
  switch (format) {
    case ReportFormat::json:
      return report_json(a, opt).dump(2) + "\n";
    case ReportFormat::text:
      return render_text(a, opt);
    case ReportFormat::markdown:
      return render_markdown(a, opt);
    case ReportFormat::latex:
      return render_latex(a);
  }
  return {};
}

}  // namespace obsynth
