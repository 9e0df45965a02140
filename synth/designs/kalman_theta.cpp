#include "designs/kalman_theta.hpp"

#include <fmt/format.h>

#include <algorithm>

#include "analysis/observability.hpp"
#include "analysis/persistence.hpp"
#include "analysis/triangular_form.hpp"
#include "designs/design_helpers.hpp"
#include "designs/options.hpp"
#include "front/fresh_names.hpp"
#include "symbolic/expr_print.hpp"
#include "symbolic/symbolic.hpp"

namespace obsynth {

using GiNaC::ex;
using GiNaC::numeric;

namespace {

std::string numbers_text(const std::vector<numeric>& v) {
  std::vector<std::string> s;
  for (const auto& q : v) s.push_back(to_string(q));
  return fmt::format("{}", fmt::join(s, ", "));
}

// The form the observer runs in: seed 002's z' = A(u) z + phi(u, z), y = z1,
//  - directly in x (z = x, triangular_in_x): w starts with the states themselves;
//  - otherwise the analysis' triangular form (analysis/triangular_form.hpp): z a permutation of
//    the states or z = (h, L_f h, ..., L_f^{n-1} h); the observer runs in zh, started from
//    z_of_x(xh0), and its estimate is x_of_z(zh).
struct KtForm {
  bool in_x = true;
  TriangularForm::Coordinates coordinates = TriangularForm::Coordinates::states;
  std::vector<GiNaC::symbol> z;     // the first n symbols of w
  ExVec a;                          // a_1(u) .. a_{n-1}(u)
  ExVec phi;                        // phi_i(u, z)
  ExVec field;                      // A(u) z + phi(u, z), in the z symbols
  ExVec z_of_x, x_of_z;             // empty when in_x
  std::vector<std::size_t> blocks;  // one per output (p = 1: {n}); C picks each block's first z
};

// The rows where C^T C has its ones (block starts), and C as text.
std::vector<std::size_t> output_rows(const KtForm& f) {
  return block_starts(f.blocks);
}

std::string C_text(const KtForm& f) {
  if (f.blocks.size() <= 1) return "C = e_1";
  std::vector<std::string> e;
  for (const std::size_t r : output_rows(f)) e.push_back(fmt::format("e_{}", r + 1));
  return fmt::format("C = [{}]^T (blocks {})", fmt::join(e, ", "), fmt::join(f.blocks, ", "));
}

// The states the outputs are when the form is in x: "x1", or "(x1, x3)".
std::string output_states_text(const Model& m, const KtForm& f) {
  std::vector<std::string> names;
  for (const std::size_t r : output_rows(f)) names.push_back(m.states[r].get_name());
  return names.size() == 1 ? names[0] : fmt::format("({})", fmt::join(names, ", "));
}

std::string coordinates_text(const KtForm& f) {
  if (f.in_x) return "in x";
  if (f.blocks.size() > 1) return "in the block coordinates z_{i,j} = L_f^{j-1} h_i";
  return f.coordinates == TriangularForm::Coordinates::states
             ? "in the states reordered (z a permutation of x)"
             : "in the coordinates z = (h, L_f h, ..., L_f^{n-1} h)";
}

KtForm from_triangular(const TriangularForm& t) {
  KtForm f;
  f.in_x = false;
  f.coordinates = t.coordinates;
  f.z = t.z;
  f.a = t.a;
  f.phi = t.phi;
  f.z_of_x = t.z_of_x;
  f.x_of_z = t.x_of_z;
  const std::size_t n = t.z.size();
  f.blocks = t.blocks.empty() ? std::vector<std::size_t>{n} : t.blocks;
  for (std::size_t i = 0; i < n; ++i) {
    ex e = t.phi[i];
    for (std::size_t j = 0; j < n; ++j)
      if (!t.A[i][j].is_zero()) e += t.A[i][j] * t.z[j];
    f.field.push_back(e);
  }
  return f;
}

// Directly in x first (the model's own states, no change of coordinates), then the analysis'
// triangular form. `compute`: when the analysis has none because it did not run, search now
// (build, the user asked for this design); otherwise report that it is undecided.
std::optional<KtForm> find_form(const Analysis& a, bool compute, std::string& why) {
  const Model& m = a.model;
  std::string why_x;
  if (const auto t = triangular_in_x(m, &why_x)) {
    KtForm f;
    f.z.assign(m.states.begin(), m.states.end());
    f.a = t->a;
    f.phi = t->phi;
    f.field = m.field();
    f.blocks = t->blocks.empty() ? std::vector<std::size_t>{m.n()} : t->blocks;
    return f;
  }
  if (m.p() > 1) {  // the block form in z_{i,j} = L_f^{j-1} h_i (small models: computed here)
    std::string why_b;
    if (const auto t = block_triangular_form(m, a.observability.indices, &why_b))
      return from_triangular(*t);
    why = fmt::format(
        "not in seed 002's block form z' = A(u) z + phi(u, z), y = C z in x ({}), nor in the "
        "block coordinates z_{{i,j}} = L_f^{{j-1}} h_i ({})",
        why_x, why_b);
    return std::nullopt;
  }
  const ObservabilityUnderInputs& ui = a.under_inputs;
  if (ui.triangular) return from_triangular(*ui.triangular);
  std::string why_t = ui.triangular_note;
  if (!ui.computed) {
    if (!compute) {
      why = fmt::format(
          "not in seed 002's form in x ({}); the triangular form in other coordinates is "
          "undecided (observability under inputs {})",
          why_x, ui.reason.empty() ? std::string("not computed") : ui.reason);
      return std::nullopt;
    }
    if (const auto t = triangular_form(m, &why_t)) return from_triangular(*t);
  }
  why = fmt::format(
      "not in seed 002's form z' = A(u) z + phi(u, z), y = z1 in x ({}), nor in other "
      "coordinates ({})",
      why_x, why_t);
  return std::nullopt;
}

// The factors of x_of_z's denominators that depend on z and may vanish for a state in the
// domain box (f(z_of_x(x)), zeros_in_box; those proved nonzero there are left out): where they
// vanish the estimate is not finite (the generated estimate returns Status::non_finite).
std::string denominators_text(const Model& m, const KtForm& form) {
  GiNaC::exmap at_x;
  for (std::size_t i = 0; i < form.z.size(); ++i) at_x[form.z[i]] = form.z_of_x[i];
  const SampleBoxes boxes = m.sample_boxes();
  std::vector<std::string> seen, out;
  for (const auto& e : form.x_of_z)
    for (const auto& f : dependent_factors(GiNaC::denom(GiNaC::normal(e)), form.z)) {
      const std::string t = to_string(f);
      if (std::find(seen.begin(), seen.end(), t) != seen.end()) continue;
      seen.push_back(t);
      const BoxZeros zx = zeros_in_box(f.subs(at_x), boxes);
      if (zx.kind == BoxZeros::never) continue;
      out.push_back(fmt::format("{} = 0 ({})", t,
                                zx.kind == BoxZeros::somewhere
                                    ? "meets the domain box: " + zx.detail
                                    : "not proved to stay out of the domain box"));
    }
  if (out.empty()) return "";
  return fmt::format("; not finite where {}", fmt::join(out, "; "));
}

std::string form_text(const KtForm& form) {
  if (form.in_x)
    return fmt::format("in seed 002's form in x with a(u) = [{}]",
                       fmt::join(to_strings(form.a), ", "));
  return fmt::format(
      "in seed 002's form {}, z = [{}], with a(u) = [{}] (the observer runs in z and estimates "
      "x = [{}])",
      coordinates_text(form), fmt::join(to_strings(form.z_of_x), ", "),
      fmt::join(to_strings(form.a), ", "), fmt::join(to_strings(form.x_of_z), ", "));
}

// Whether every input is strongly persistent: a free of u and nonzero on the parameter box.
// Then A is a constant nilpotent matrix, Psi(t, theta) tends to the same limit for every input,
// and scaling z_i by theta^(i-1) / (a_1 ... a_{i-1}) makes alpha(theta) and Gamma_ii / Gamma_jj
// (theta >= 1) constants: i) and ii) of the Definition hold whatever u.
// With blocks, the same block by block (the superdiagonal between blocks is zero by structure).
bool every_input_persistent(const Model& m, const KtForm& form) {
  const SampleBoxes boxes = m.sample_boxes();
  const auto starts = output_rows(form);
  for (std::size_t i = 0; i < form.a.size(); ++i) {
    if (std::find(starts.begin(), starts.end(), i + 1) != starts.end()) continue;
    const ex& ai = form.a[i];
    if (depends_on(ai, m.inputs) || zeros_in_box(ai, boxes).kind != BoxZeros::never) return false;
  }
  return true;
}

// The guarantee the Theorem gives here. Never rigorous: it proves convergence for theta above
// a threshold it does not make explicit, so no chosen theta is proven sufficient.
void set_guarantee(Verdict& v, const Model& m, const KtForm& form, const PhiLipschitz& lip) {
  const std::string singular_estimate = form.in_x ? "" : denominators_text(m, form);
  // Seed 002 states its Theorem for y = z1; the proof uses only that the scaling Delta_theta =
  // diag(theta^-(level-1)) gives Delta A(u) Delta^-1 = theta A(u) and C Delta^-1 = C, and that
  // phi is triangular by level, so it carries over to the block form, which has all three by
  // construction (A links level j + 1 to level j inside a block, C picks level 1).
  const std::string blocks_note =
      form.blocks.size() > 1
          ? "; p > 1: seed 002 proves its Theorem for y = z1, and the proof carries over to this "
            "block form unchanged (it uses only Delta_theta A(u) Delta_theta^-1 = theta A(u), "
            "C Delta_theta^-1 = C and phi triangular by level, which the block form has by "
            "construction)"
          : "";
  if (lip.kind != PhiLipschitz::proved) {
    v.guarantee = Guarantee::none;
    v.guarantee_text = lip.text + blocks_note;
  } else if (!every_input_persistent(m, form)) {
    v.guarantee = Guarantee::none;
    v.guarantee_text =
        "for an unknown input: a(u) depends on the input (or may vanish), so convergence "
        "needs a strongly persistent input; `obsynth check --input ... --horizon ...` checks "
        "one (sampled)" +
        blocks_note;
  } else if (!singular_estimate.empty()) {
    v.guarantee = Guarantee::none;
    v.guarantee_text = "in x: zh -> z holds for theta large enough, but the estimate x_of_z" +
                       singular_estimate.substr(1) + blocks_note;
  } else {
    v.guarantee = Guarantee::partial;
    v.guarantee_text =
        "the Theorem's hypotheses are proved on the domain box for every input (a "
        "constant: every input strongly persistent; " +
        lip.text +
        "), but the Theorem gives convergence only for theta above a threshold it does not make "
        "explicit (theta is not proven large enough), and only while x and xh stay in the box" +
        blocks_note;
  }
}

Verdict applies(const Analysis& a) {
  Verdict v;
  std::string why;
  const auto form = find_form(a, false, why);
  if (!form) {
    v.reasons.push_back(why);
    return v;
  }
  const PhiLipschitz lip = phi_lipschitz_on_box(a.model, form->z, form->phi, form->z_of_x);
  if (lip.kind == PhiLipschitz::fails) {
    v.reasons.push_back(form_text(*form) +
                        ", but seed 002's Theorem needs phi(u, z) Lipschitz in z, whatever "
                        "the input: " +
                        lip.text);
    return v;
  }
  v.applies = true;
  v.reasons.push_back(form_text(*form) +
                      ": converges for strongly persistent inputs and theta large enough (check "
                      "an input with `obsynth check --input ... --horizon ...`)");
  set_guarantee(v, a.model, *form, lip);
  return v;
}

numeric chosen_theta(const DesignOptions& o) {
  const auto t = real_option(o, "theta");
  if (!t) return numeric(5);
  if (!t->is_positive())
    throw UserError(SourceLoc{}, fmt::format("--theta: {} is not positive", to_string(*t)));
  return *t;
}

// S0 as a full symmetric matrix: one value s (s I), n values (diagonal) or n(n+1)/2 values
// (packed upper triangle, row by row); must be positive definite.
std::vector<std::vector<numeric>> chosen_S0(const DesignOptions& o, std::size_t n) {
  std::vector<numeric> v = real_list_option(o, "S0");
  std::vector<std::vector<numeric>> S(n, std::vector<numeric>(n, 0));
  if (v.empty()) v = {1};
  if (v.size() == 1) {
    for (std::size_t i = 0; i < n; ++i) S[i][i] = v[0];
  } else if (v.size() == n) {
    for (std::size_t i = 0; i < n; ++i) S[i][i] = v[i];
  } else if (v.size() == n * (n + 1) / 2) {
    std::size_t k = 0;
    for (std::size_t r = 0; r < n; ++r)
      for (std::size_t c = r; c < n; ++c) S[r][c] = S[c][r] = v[k++];
  } else {
    throw UserError(SourceLoc{},
                    fmt::format("--S0: expected 1, {} or {} numbers (s I, diagonal, packed upper "
                                "triangle), got {}",
                                n, n * (n + 1) / 2, v.size()));
  }
  // Positive definite: exact Sylvester criterion on leading minors.
  GiNaC::matrix M(static_cast<unsigned>(n), static_cast<unsigned>(n));
  for (std::size_t r = 0; r < n; ++r)
    for (std::size_t c = 0; c < n; ++c)
      M(static_cast<unsigned>(r), static_cast<unsigned>(c)) = S[r][c];
  for (unsigned k = 1; k <= n; ++k) {
    GiNaC::matrix L(k, k);
    for (unsigned r = 0; r < k; ++r)
      for (unsigned c = 0; c < k; ++c) L(r, c) = M(r, c);
    const ex d = L.determinant();
    if (!GiNaC::is_a<numeric>(d) || !GiNaC::ex_to<numeric>(d).is_positive())
      throw UserError(SourceLoc{}, "--S0: the matrix is not positive definite");
  }
  return S;
}

using ExMatrix = std::vector<std::vector<ex>>;

// The observer state w = (zh, S packed): zh (the states themselves when the form is in x, the
// form's z symbols otherwise), then S_r_c (r <= c), created in that order (it fixes GiNaC's term
// order in the output).
struct KtSymbols {
  std::vector<GiNaC::symbol> w;
  ExMatrix S;  // n x n, symmetric, entries from w
};

KtSymbols kt_symbols(const KtForm& form) {
  const std::size_t n = form.z.size();
  KtSymbols sym;
  sym.w.assign(form.z.begin(), form.z.end());
  sym.S.assign(n, std::vector<ex>(n));
  for (std::size_t r = 0; r < n; ++r)
    for (std::size_t c = r; c < n; ++c) {
      GiNaC::symbol q(fmt::format("S_{}_{}", r + 1, c + 1));
      sym.w.push_back(q);
      sym.S[r][c] = sym.S[c][r] = q;
    }
  return sym;
}

// zh' = A(u) zh + phi(u, zh), then S' = -theta S - A^T S - S A + C^T C packed.
ExVec kt_rhs(const KtForm& form, const ExMatrix& S, const numeric& theta) {
  const std::size_t n = form.z.size();
  ExMatrix A(n, std::vector<ex>(n, 0));
  for (std::size_t i = 0; i + 1 < n; ++i) A[i][i + 1] = form.a[i];
  ExVec rhs = form.field;
  const auto outs = output_rows(form);
  for (std::size_t r = 0; r < n; ++r)
    for (std::size_t c = r; c < n; ++c) {
      const bool CtC = r == c && std::find(outs.begin(), outs.end(), r) != outs.end();
      ex acc = -theta * S[r][c] + (CtC ? 1 : 0);
      for (std::size_t k = 0; k < n; ++k) acc -= A[k][r] * S[k][c] + S[r][k] * A[k][c];
      rhs.push_back(acc);
    }
  return rhs;
}

// The generated functions (rhs, gain vector, init, estimate) and their roles. Out of x the
// init is (z_of_x(xh0), S0) and the estimate x_of_z(zh).
void add_kt_functions(ObserverSpec& s, const Model& m, const KtForm& form, const KtSymbols& sym,
                      const ExVec& rhs, const std::vector<numeric>& S0packed) {
  const std::vector<GiNaC::symbol> y = measurement_symbols(m);
  const FunctionArg w = vector_arg("w", "ObserverState", sym.w, FunctionArg::Kind::observer_state);
  const FunctionArg u = input_arg(m), yarg = output_arg(y);
  s.functions.push_back(
      make_function("kt_rhs",
                    "zh' = A(u) zh + phi(u, zh); S' = -theta S - A(u)^T S - S A(u) + C^T C "
                    "(packed); the gain is added by a Cholesky solve with S.",
                    {w, u, yarg}, rhs, "ObserverState"));
  ExVec v(m.n(), 0);  // -C^T (C zh - y): y_i - zh at the first row of block i
  const auto outs = output_rows(form);
  for (std::size_t i = 0; i < outs.size(); ++i) v[outs[i]] = y[i] - form.z[outs[i]];
  s.functions.push_back(make_function("kt_gain_vector", "-C^T (C zh - y), solved with S.",
                                      {w, u, yarg}, v, "GainVector"));
  ExVec init = form.in_x ? ExVec(m.states.begin(), m.states.end()) : form.z_of_x;
  init.insert(init.end(), S0packed.begin(), S0packed.end());
  s.functions.push_back(make_function(
      "kt_init", form.in_x ? "w = (xh0, S0 packed)." : "w = (z(xh0), S0 packed), z = z_of_x.",
      {state_arg(m)}, init, "ObserverState"));
  ExVec est = form.in_x ? ExVec(m.states.begin(), m.states.end()) : form.x_of_z;
  s.functions.push_back(make_function("kt_estimate",
                                      form.in_x ? "xh = zh (the first n entries of w)."
                                                : "xh = x_of_z(zh) (the first n entries of w).",
                                      {w}, est, "State"));
  s.init = InitKind::function;
  s.roles.init = "kt_init";
  s.update = UpdateKind::ode;
  s.roles.rhs = "kt_rhs";
  s.estimate = EstimateKind::function;
  s.roles.estimate = "kt_estimate";
}

// The gain S^-1 C^T (y - C zh), added to zh' by a Cholesky solve with the block S.
SolveCorrection kt_correction(std::size_t n) {
  SolveCorrection corr;
  corr.factor = SolveCorrection::Factor::cholesky;
  corr.matrix_block = "S";
  corr.vector_function = "kt_gain_vector";
  corr.target_offset = 0;
  corr.dim = n;
  corr.singular_doc =
      "S is not positive definite (it stays so in exact arithmetic; loss is numerical: a step "
      "with dt theta > 1.2956, or a non-persistent input over a long time)";
  return corr;
}

// The class documentation's line on convergence: the Theorem's claim only where it applies.
std::string theorem_line(const PhiLipschitz& lip) {
  if (lip.kind == PhiLipschitz::fails)
    return "NOT covered by seed 002's Theorem: phi is not Lipschitz in z on the domain box.";
  if (lip.kind == PhiLipschitz::unknown)
    return "Converges for strongly persistent inputs (seed 002, Theorem) if phi is Lipschitz in "
           "z (not proved).";
  return "Converges for strongly persistent inputs (seed 002, Theorem).";
}

// The step is RK4 on (zh, S) with the gain solved with S in every stage (a stage whose S is not
// positive definite is rejected). Along a direction that C^T C does not feed, S' = -theta S
// (A = 0, e.g. u = 0 in seed 002's example (4)) gives the stages S, (1 - h/2) S,
// (1 - h/2 + h^2/4) S and (1 - h + h^2/2 - h^3/4) S, h = dt theta: the last one turns negative
// for h > 1.29560, the real root of 1 - h + h^2/2 - h^3/4 (bisection; RK4's own stability,
// h < 2.78529, is looser). So dt < 1.2956 / theta is necessary (measured on dufour4, u = 1,
// theta = 50: dt = 0.0255 converges, 0.026 is rejected at t = 0); d phi/d z adds to the zh
// equation's eigenvalues, so it is not sufficient.
constexpr double kStagePositivity = 1.2956;

std::string safe_period_text(const numeric& theta) {
  return fmt::format(
      "dt < {:.4g} = 1.2956 / theta (necessary: beyond it the last RK4 stage of S' = -theta S "
      "- A^T S - S A + C^T C loses positive definiteness in a direction C^T C does not feed, and "
      "the step is rejected with Status::singular); not sufficient: d phi/d z adds to the zh "
      "equation's eigenvalues",
      kStagePositivity / theta.to_double());
}

// Title, description, class documentation, constants, report rows and summary.
void describe_kt(ObserverSpec& s, const Model& m, const KtForm& form, const numeric& theta,
                 const std::vector<numeric>& S0packed, const DesignOptions& o,
                 const PhiLipschitz& lip, const Verdict& guarantee) {
  const std::string as = fmt::format("{}", fmt::join(to_strings(form.a), ", "));
  const std::string phis = fmt::format("{}", fmt::join(to_strings(form.phi), ", "));
  s.title = "Kalman-like theta observer (Dufour-Flila-Hammouri)";
  s.description = {"Observer: Kalman-like theta observer (seed 002 eq. 7/10)"};
  if (form.in_x) {
    s.description.push_back(
        fmt::format("Form in x: a(u) = [{}], y = {}; theta = {}; S0 (packed) = [{}]", as,
                    output_states_text(m, form), to_string(theta), numbers_text(S0packed)));
  } else {
    s.description.push_back(fmt::format(
        "Form {}: z = [{}], a(u) = [{}]; theta = {}; S0 (packed) = [{}]", coordinates_text(form),
        fmt::join(to_strings(form.z_of_x), ", "), as, to_string(theta), numbers_text(S0packed)));
    s.description.push_back(
        fmt::format("Estimate x = x_of_z(zh) = [{}]", fmt::join(to_strings(form.x_of_z), ", ")));
  }
  s.description.push_back(
      "Gain S^-1 C^T (y - C zh) by a Cholesky solve; S not positive definite -> "
      "Status::singular");
  s.class_doc = {"  zh' = A(u) zh + phi(u, zh) - S^-1 C^T (C zh - y)",
                 "  S'  = -theta S - A(u)^T S - S A(u) + C^T C", theorem_line(lip)};
  if (!form.in_x)
    s.class_doc.insert(s.class_doc.begin() + 2,
                       fmt::format("in z = [{}], started at z(xh0); estimate xh = [{}].",
                                   fmt::join(to_strings(form.z_of_x), ", "),
                                   fmt::join(to_strings(form.x_of_z), ", ")));
  s.constants.push_back({"theta", {theta}, "forgetting rate of S"});
  s.constants.push_back({"S0", S0packed, "initial S, packed upper triangle"});
  s.largest_safe_step = kStagePositivity / theta.to_double();
  if (form.in_x) {
    s.report = {
        {"form", fmt::format("z = x, a(u) = [{}], phi = [{}], {}", as, phis, C_text(form))}};
  } else {
    std::vector<std::string> zs;
    for (const auto& z : form.z) zs.push_back(z.get_name());
    s.report = {{"coordinates", fmt::format("{} ({}): [{}] = [{}]", coordinates_text(form),
                                            coordinates_name(form.coordinates), fmt::join(zs, ", "),
                                            fmt::join(to_strings(form.z_of_x), ", "))},
                {"form", fmt::format("a(u) = [{}], phi(u, z) = [{}], {}", as, phis, C_text(form))},
                {"estimate", fmt::format("x = x_of_z(zh) = [{}] (explicit inverse; zh starts at "
                                         "z(xh0)){}",
                                         fmt::join(to_strings(form.x_of_z), ", "),
                                         denominators_text(m, form))}};
  }
  const std::string conv =
      lip.kind == PhiLipschitz::fails
          ? "NOT covered by seed 002's Theorem, whatever the input and theta: " + lip.text
          : "for strongly persistent inputs (seed 002's Theorem, phi globally Lipschitz in z) and "
            "theta large enough; check an input with `obsynth check model.sym --input \"...\" "
            "--horizon T`";
  s.report.insert(
      s.report.end(),
      {{"theta", to_string(theta) + (o.find("theta") ? "" : " (default)")},
       {"S0 (packed)", numbers_text(S0packed) + (o.find("S0") ? "" : " (default: identity)")},
       {"gain", "S^-1 C^T (y - C zh), Cholesky solve with S"},
       {"phi Lipschitz in z", lip.text},
       {"guarantee",
        fmt::format("{}: {}", guarantee_name(guarantee.guarantee), guarantee.guarantee_text)},
       {"largest safe sample period", safe_period_text(theta)},
       {"convergence", form.in_x
                           ? conv
                           : conv + "; the theorem is about zh - z: xh - x follows where x_of_z is "
                                    "continuous along the trajectory"}});
  s.summary = fmt::format(
      "Kalman-like theta observer{}, theta = {}, S0 = [{}] (packed); {}",
      form.in_x ? "" : " " + coordinates_text(form), to_string(theta), numbers_text(S0packed),
      lip.kind == PhiLipschitz::fails
          ? "NOT covered by seed 002's Theorem (phi is not Lipschitz in z on the domain box)"
          : "converges for strongly persistent inputs and theta large enough");
}

ObserverSpec build(const Analysis& a, const DesignOptions& o) {
  const Model& m = a.model;
  std::string why;
  const auto form = find_form(a, true, why);
  if (!form)
    throw UserError(SourceLoc{m.file, 0, 0}, "method 'kalman-theta' does not apply: " + why);
  const std::size_t n = m.n();
  const numeric theta = chosen_theta(o);
  const auto S0 = chosen_S0(o, n);
  std::vector<numeric> S0packed;
  for (std::size_t r = 0; r < n; ++r)
    for (std::size_t c = r; c < n; ++c) S0packed.push_back(S0[r][c]);

  ObserverSpec s;
  s.method = "kalman-theta";
  s.class_suffix = "KalmanTheta";
  s.state_name = "w";
  s.state_doc = form->in_x
                    ? "(zh, S): the estimate zh = xh, then S packed (upper triangle, row by row)"
                    : "(zh, S): zh in the form's coordinates z (xh = x_of_z(zh)), then S packed "
                      "(upper triangle, row by row)";
  SymmetricBlock block;
  block.name = "S";
  block.offset = n;
  block.dim = n;
  block.keep_positive_definite = true;
  s.state_size = n + block.packed_size();
  s.symmetric_blocks.push_back(block);
  s.params = runtime_params(m);
  s.functions = model_functions(m);

  const KtSymbols sym = kt_symbols(*form);
  add_kt_functions(s, m, *form, sym, kt_rhs(*form, sym.S, theta), S0packed);
  s.correction = kt_correction(n);
  const PhiLipschitz lip = phi_lipschitz_on_box(m, form->z, form->phi, form->z_of_x);
  Verdict guarantee;
  set_guarantee(guarantee, m, *form, lip);
  describe_kt(s, m, *form, theta, S0packed, o, lip, guarantee);
  return s;
}

}  // namespace

Design kalman_theta_design() {
  Design d;
  d.name = "kalman-theta";
  d.summary =
      "Kalman-like theta observer for systems not uniformly observable, p >= 1 outputs in "
      "seed 002's form block by block (seed 002 eq. 7/10; needs a strongly persistent input)";
  d.options = {
      {"theta",
       "high-gain: gain scale theta (Delta_theta = diag(theta, ..., theta^k) per block); "
       "kalman-theta: forgetting rate theta of S",
       "5 (high-gain), 5 (kalman-theta)"},
      {"S0", "kalman-theta: initial S (s, or n diagonal values, or the packed upper triangle)",
       "identity"}};
  d.plan = stateless_plan<applies, build>;
  d.observes_along_inputs = true;
  d.along_inputs_note = "Kalman-like, strongly persistent inputs";
  d.max_outputs = 0;  // y = C z, one block per output (seed 002's form block by block)
  return d;
}

}  // namespace obsynth
