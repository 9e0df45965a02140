#include "analysis/observability_inputs.hpp"

#include <fmt/format.h>

#include <new>

#include "analysis/observability_ring.hpp"
#include "symbolic/expr_print.hpp"
#include "symbolic/symbolic.hpp"
#include "symbolic/zero_test.hpp"

namespace obsynth {

using GiNaC::ex;
using GiNaC::numeric;

Model frozen_input_model(const Model& m) {
  Model mu = m;
  mu.f = m.field();
  mu.g.assign(m.n(), ex(0));
  mu.inputs.clear();
  for (const auto& u : m.inputs) {
    mu.domain[u.get_name()] = m.box(u);
    mu.params.push_back(Param{u.get_name(), u, std::nullopt, SourceLoc{}});
  }
  return mu;
}

namespace {

std::string rank_method_name(const Observability& ob) {
  return ob.jets         ? "jets"
         : ob.triangular ? "triangular"
         : ob.rank_exact ? "exact"
                         : "high-precision";
}

bool input_enters(const Model& m) {
  if (m.inputs.empty()) return false;
  for (const auto& e : m.g)
    if (!e.is_zero()) return true;
  for (const auto& e : m.h)
    if (depends_on(e, m.inputs)) return true;
  return false;
}

// Independent input values v_k (one copy of the inputs per word position, "u__v<k>", sampled
// in u's box) and the substitutions u -> v_k.
struct InputCopies {
  std::vector<std::vector<GiNaC::symbol>> v;
  std::vector<GiNaC::exmap> to_v;
};

InputCopies input_copies(const Model& m, SampleBoxes& boxes) {
  const std::size_t n = m.n();
  InputCopies c{std::vector<std::vector<GiNaC::symbol>>(n), std::vector<GiNaC::exmap>(n)};
  for (std::size_t k = 0; k < n; ++k)
    for (const auto& u : m.inputs) {
      const std::string name = fmt::format("{}__v{}", u.get_name(), k);
      c.v[k].emplace_back(name);
      boxes.by_name[name] = m.box(u);
      c.to_v[k][u] = c.v[k].back();
    }
  return c;
}

// grads[k][i]: the gradient in x of L_{X_k} ... L_{X_1} h_i(x, v_0), X_j = f + g(., v_j).
std::vector<ExMatrix> word_gradients(const Model& m, const std::vector<GiNaC::exmap>& to_v,
                                     Budget& budget) {
  const std::size_t n = m.n();
  const ExVec field = m.field();
  std::vector<ExMatrix> grads;
  std::vector<ex> phi;
  for (const auto& h : m.h) phi.push_back(h.subs(to_v[0]));
  for (std::size_t k = 0; k < n; ++k) {
    if (k > 0) {
      ExVec Fk;
      for (const auto& e : field) Fk.push_back(e.subs(to_v[k]));
      for (auto& p : phi) p = GiNaC::expand(lie_derivative(p, Fk, m.states));
    }
    ExMatrix rows;
    for (const auto& p : phi) {
      rows.push_back(gradient(p, m.states));
      budget.check(expression_size(p));
    }
    grads.push_back(std::move(rows));
  }
  return grads;
}

// One gradient entry at pt: exact when the gradients have no transcendental function, else in
// high precision with values below the rounding (relative to the magnitude) set to 0. False
// where it is undefined.
bool entry_at(const ex& e, const GiNaC::exmap& pt, bool exact, const numeric& rounding,
              const ObservabilityOptions& opt, numeric& val) {
  if (exact) {
    ex e0;
    try {
      e0 = e.subs(pt);
    } catch (const std::exception&) {
      return false;
    }
    if (!GiNaC::is_a<numeric>(e0)) return false;
    val = GiNaC::ex_to<numeric>(e0);
    return true;
  }
  numeric mag;
  if (!evaluate_with_magnitude(e, pt, opt.float_digits, val, mag)) return false;
  if (GiNaC::abs(val) <= rounding * mag) val = 0;
  return true;
}

// Appends the rows of every word's gradients at pt to a; false where one is undefined.
bool append_rows_at(const std::vector<ExMatrix>& grads, const GiNaC::exmap& pt, bool exact,
                    const numeric& rounding, const ObservabilityOptions& opt,
                    std::vector<std::vector<numeric>>& a) {
  for (const auto& word : grads)
    for (const auto& row : word) {
      std::vector<numeric> r;
      for (const auto& e : row) {
        numeric val;
        if (!entry_at(e, pt, exact, rounding, opt, val)) return false;
        r.push_back(val);
      }
      a.push_back(std::move(r));
    }
  return true;
}

// The rank of the observation space: d of L_{X_k} ... L_{X_1} h, X_j = f + g(., v_j) with
// independent input values v_j (and h(x, v_0)), words of length < n, several random input
// tuples per length, at two random state points; the largest rank seen.
std::size_t observation_space_rank(const Model& m, Budget& budget,
                                   const ObservabilityOptions& opt) {
  const std::size_t n = m.n();
  SampleBoxes boxes = m.sample_boxes();
  const InputCopies copies = input_copies(m, boxes);
  const std::vector<ExMatrix> grads = word_gradients(m, copies.to_v, budget);
  bool exact = true;
  for (const auto& rows : grads)
    for (const auto& r : rows)
      for (const auto& e : r)
        if (has_transcendental(e)) exact = false;
  std::vector<GiNaC::symbol> syms(m.states);
  for (const auto& s : m.free_params()) syms.push_back(s);
  std::vector<GiNaC::symbol> vsyms;
  for (const auto& vk : copies.v) vsyms.insert(vsyms.end(), vk.begin(), vk.end());
  const int tuples = static_cast<int>(n) + 2;
  const auto xpoints = sample_points(syms, boxes, 8, opt.seed);
  const auto vpoints = sample_points(vsyms, boxes, tuples, opt.seed + 1);
  const numeric rounding = numeric(10).power(-(opt.float_digits - 10));
  std::size_t best = 0;
  int used = 0;
  for (const auto& xp : xpoints) {
    if (used >= 2) break;
    std::vector<std::vector<numeric>> a;
    bool valid = true;
    for (std::size_t t = 0; t < vpoints.size() && valid; ++t) {
      GiNaC::exmap pt = xp;
      for (const auto& [s, val] : vpoints[t]) pt[s] = val;
      valid = append_rows_at(grads, pt, exact, rounding, opt, a);
    }
    if (!valid) continue;
    ++used;
    best = std::max(best, numeric_rank(a, exact));
    budget.check();
    if (best == n) break;
  }
  if (used == 0)
    throw UserError(SourceLoc{}, "the observation space is undefined at every sampled point");
  return best;
}

std::string list_text(const std::vector<std::string>& v) {
  return fmt::format("{}", fmt::join(v, "; "));
}

// rank O_u < n for every constant input: the observation space (all input sequences), when
// computed, says whether a time-varying input can help.
void decide_rank_deficient(std::size_t n, ObservabilityUnderInputs& r) {
  r.uniformly_observable = false;
  if (r.observation_space_rank && *r.observation_space_rank < n) {
    r.observable_for_some_input = false;
    r.reason = fmt::format(
        "no input makes the model observable: rank O_u = {} < n = {} for every constant input, "
        "and the observation space (all input sequences) has rank {} < n",
        r.generic_rank, n, *r.observation_space_rank);
  } else if (r.observation_space_rank) {
    r.observable_for_some_input = true;
    r.reason = fmt::format(
        "rank O_u = {} < n = {} for every constant input, but the observation space has rank "
        "n: only time-varying inputs make the model observable",
        r.generic_rank, n);
  } else {
    r.reason = fmt::format(
        "rank O_u = {} < n = {} for every constant input; whether a time-varying input helps "
        "is undecided",
        r.generic_rank, n);
  }
}

// In the coordinates (h, L_f h, ...), the chart must be regular and defined on the domain
// box: why it may not be (zeros of the rank-drop factors or poles of O), or nullopt.
std::optional<std::string> chart_doubt(const Observability& drift, const SampleBoxes& boxes) {
  std::vector<std::string> chart_bad, chart_unknown;
  for (const auto& f : drift.rank_drop) {
    const BoxZeros z = zeros_in_box(f, boxes);
    if (z.kind == BoxZeros::somewhere) chart_bad.push_back(z.detail);
    if (z.kind == BoxZeros::unknown) chart_unknown.push_back(z.detail);
  }
  if (drift.undefined.empty() && chart_bad.empty() && chart_unknown.empty()) return std::nullopt;
  return list_text(
      !chart_bad.empty() ? chart_bad
      : !chart_unknown.empty()
          ? chart_unknown
          : std::vector<std::string>{"O has poles: " + list_text(to_strings(drift.undefined))});
}

// Triangular form (seed 002 eq. 1-2): uniformly observable iff every a_i(u) stays nonzero on
// the input box (and, in Lie-derivative coordinates, the chart is regular on the domain).
void decide_triangular(const TriangularForm& t, const Observability& drift,
                       const SampleBoxes& boxes, const std::string& drift_note,
                       ObservabilityUnderInputs& r) {
  std::vector<std::string> vanish, unknown;
  for (std::size_t i = 0; i < t.a.size(); ++i) {
    const BoxZeros z = zeros_in_box(t.a[i], boxes);
    if (z.kind == BoxZeros::somewhere)
      vanish.push_back(fmt::format("a_{}(u) = {}: {}", i + 1, to_string(t.a[i]), z.detail));
    if (z.kind == BoxZeros::unknown)
      unknown.push_back(fmt::format("a_{}(u) = {}: {}", i + 1, to_string(t.a[i]), z.detail));
  }
  const bool lie = t.coordinates == TriangularForm::Coordinates::lie_derivatives;
  const std::string where = lie ? "in the coordinates (h, L_f h, ...)" : "in the states";
  if (!vanish.empty()) {
    r.uniformly_observable = false;
    r.reason = fmt::format(
        "triangular form (seed 002 eq. 1-2) {}; not uniformly observable: {}; observable "
        "under inputs that keep it away from zero persistently{}",
        where, list_text(vanish), drift_note);
    return;
  }
  if (!unknown.empty()) {
    r.reason = fmt::format("triangular form {}; undecided: {}", where, list_text(unknown));
    return;
  }
  if (lie)
    if (const auto doubt = chart_doubt(drift, boxes)) {
      r.reason = fmt::format(
          "triangular form in the coordinates (h, L_f h, ...) with a_i = 1, but those "
          "coordinates are singular or undefined somewhere in the domain box ({}); undecided",
          *doubt);
      return;
    }
  r.uniformly_observable = true;
  r.reason = fmt::format(
      "triangular form (seed 002 eq. 1-2) {} with every a_i(u) nonzero on the input box "
      "(proved){}",
      where, lie ? " and the coordinates' Jacobian det O nonzero on the domain box" : "");
}

// No triangular form: singular inputs that are admissible (rank O_u < n for every x there; an
// analytic model with a constant input is then not observable anywhere) disprove uniform
// observability; otherwise undecided.
void decide_from_singular_inputs(const Model& m, ObservabilityUnderInputs& r) {
  std::vector<std::string> admissible, unsure;
  for (const auto& s : r.singular) {
    if (s.in_box.kind == BoxZeros::somewhere) admissible.push_back(s.in_box.detail);
    if (s.in_box.kind == BoxZeros::unknown) unsure.push_back(s.in_box.detail);
  }
  // With several outputs det O_u is one maximal minor: another minor may stay regular where it
  // vanishes, so its zeros decide nothing.
  if (!admissible.empty() && m.p() > 1) {
    r.reason = fmt::format(
        "undecided: no triangular form ({}); the selected rows' minor of O_u vanishes at "
        "admissible inputs ({}), but other minors were not checked",
        r.triangular_note, list_text(admissible));
    return;
  }
  if (!admissible.empty()) {
    r.uniformly_observable = false;
    r.reason = fmt::format(
        "not uniformly observable: the singular input{} {} lie{} in the input box (rank O_u < n "
        "for every state there); observable under inputs that avoid {} persistently",
        admissible.size() == 1 ? "" : "s", list_text(admissible), admissible.size() == 1 ? "s" : "",
        admissible.size() == 1 ? "it" : "them");
    return;
  }
  r.reason = fmt::format(
      "undecided: no triangular form ({}){}", r.triangular_note,
      unsure.empty() ? std::string() : "; singular inputs not excluded: " + list_text(unsure));
}

void decide(const Model& m, const Observability& drift, ObservabilityUnderInputs& r) {
  const std::size_t n = m.n();
  if (r.generic_rank < n) {
    decide_rank_deficient(n, r);
    return;
  }
  r.observable_for_some_input = true;
  if (r.triangular) {
    const std::string drift_note =
        drift.generic_rank < n
            ? fmt::format(" (the drift alone, u = 0, has rank {} < n = {})", drift.generic_rank, n)
            : "";
    decide_triangular(*r.triangular, drift, m.sample_boxes(), drift_note, r);
    return;
  }
  decide_from_singular_inputs(m, r);
}

}  // namespace

ObservabilityUnderInputs analyse_observability_under_inputs(const Model& m,
                                                            const Observability& drift,
                                                            const ObservabilityOptions& opt,
                                                            const BudgetLimits& limits) {
  ObservabilityUnderInputs r;
  r.n = m.n();
  Budget budget(limits);
  try {
    budget.begin("inputs");
    Observability frozen;
    r.same_as_drift = !input_enters(m);
    // When the drift rank came from the jets (the symbolic chain was too large or not
    // wanted), so does this one, and the symbolic parts below are skipped.
    ObservabilityOptions fopt = opt;
    if (drift.jets) fopt.rank_method = RankMethod::jets;
    const ExVec* lie = !drift.jets && drift.lie.size() == 1 ? &drift.lie[0] : nullptr;
    r.triangular = triangular_form(m, &r.triangular_note, lie, !drift.jets);
    if (!r.same_as_drift) {
      // Only rank and det are needed: from the triangular form when it is in the states, else
      // observability_rank, which leaves out the expressions it can.
      const Model fm = frozen_input_model(m);
      std::optional<Observability> direct;
      if (r.triangular && !drift.jets)
        direct = observability_of_triangular_form(fm, *r.triangular, drift);
      frozen = direct ? std::move(*direct) : observability_rank(fm, budget, fopt);
    }
    const Observability& ob = r.same_as_drift ? drift : frozen;
    r.generic_rank = ob.generic_rank;
    r.rank_method = rank_method_name(ob);
    if (!ob.jets && ob.generic_rank == r.n && ob.selected.size() == r.n) {
      r.det = ob.det;
      r.rank_drop = ob.rank_drop;
      const SampleBoxes boxes = m.sample_boxes();
      for (const auto& f : dependent_factors(ob.det, m.inputs))
        if (!depends_on(f, m.states)) r.singular.push_back({f, zeros_in_box(f, boxes)});
    }
    if (r.generic_rank == r.n)
      r.observation_space_rank = r.generic_rank;
    else if (!drift.jets)
      r.observation_space_rank = observation_space_rank(m, budget, opt);
    r.computed = true;
    decide(m, drift, r);
  } catch (const BudgetExceeded& e) {
    r = ObservabilityUnderInputs{};
    r.n = m.n();
    r.reason = "not computed: " + e.reason();
  } catch (const UserError& e) {
    r = ObservabilityUnderInputs{};
    r.n = m.n();
    r.reason = "not computed: " +
               (e.diagnostics().empty() ? std::string(e.what()) : e.diagnostics()[0].message);
  } catch (const std::bad_alloc&) {
    r = ObservabilityUnderInputs{};
    r.n = m.n();
    r.reason = "not computed: ran out of memory";
  }
  budget.end();
  return r;
}

}  // namespace obsynth
