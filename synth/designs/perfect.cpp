#include "designs/perfect.hpp"

#include <fmt/format.h>

#include <algorithm>

#include "analysis/conditions.hpp"
#include "designs/canonical.hpp"
#include "designs/design_helpers.hpp"
#include "designs/options.hpp"
#include "front/fresh_names.hpp"
#include "symbolic/symbolic.hpp"

namespace obsynth {

using GiNaC::ex;

namespace {

struct Jets {
  std::vector<std::vector<GiNaC::symbol>> y;  // per output: y_q, y_q', ..., y_q^(n-1)
  std::vector<std::vector<GiNaC::symbol>> u;  // per input: u, u', ..., u^(n-2)
  // The YJet vector, output by output (y_1, y_1', ..., y_2, ...).
  std::vector<GiNaC::symbol> y_flat() const {
    std::vector<GiNaC::symbol> out;
    for (const auto& jet : y) out.insert(out.end(), jet.begin(), jet.end());
    return out;
  }
};

Jets jet_symbols(const Model& m) {
  Jets j;
  const std::size_t n = m.n();
  const auto outputs = measurement_symbols(m);
  for (const auto& y : outputs) j.y.push_back(fresh_symbols(m, y.get_name() + "_d", n, 0));
  for (const auto& u : m.inputs)
    j.u.push_back(fresh_symbols(m, u.get_name() + "_d", std::max<std::size_t>(n, 2) - 1, 0));
  return j;
}

// Total time derivative of a function of the jets.
ex total_derivative(const ex& phi, const Jets& j) {
  ex acc = 0;
  for (const auto& jet : j.y)
    for (std::size_t k = 0; k + 1 < jet.size(); ++k) acc += phi.diff(jet[k]) * jet[k + 1];
  for (const auto& jet : j.u)
    for (std::size_t k = 0; k + 1 < jet.size(); ++k) acc += phi.diff(jet[k]) * jet[k + 1];
  return simplify(acc);
}

// Procedure 1, block by block: z_{q,k_q} = y_q - y0_q, z_{i-1} = d/dt z_i - l_i(u, y).
ExVec z_of_jets(const Analysis& a, const Jets& j) {
  const Model& m = a.model;
  const CanonicalForm& cf = a.canonical;
  GiNaC::exmap to_jets;
  for (std::size_t q = 0; q < m.p(); ++q) to_jets[cf.y[q]] = j.y[q][0];
  for (std::size_t k = 0; k < m.m(); ++k) to_jets[m.inputs[k]] = j.u[k][0];
  const ExVec y0 = outputs_at_base_point(a);
  ExVec z(m.n(), 0);
  for (std::size_t q = 0; q < cf.outputs(); ++q) {
    const std::size_t end = cf.block_end(q);
    z[end] = j.y[q][0] - y0[q];
    for (std::size_t i = end; i > cf.block_start(q); --i)
      z[i - 1] = simplify(total_derivative(z[i], j) - cf.l[i].subs(to_jets));
  }
  return z;
}

// Highest derivative order of each jet that the expressions use.
void used_orders(const ExVec& used, const Jets& j, ObserverSpec& s) {
  s.y_order_used = 0;
  for (const auto& jet : j.y)
    for (std::size_t k = 0; k < jet.size(); ++k)
      for (const auto& e : used)
        if (e.has(jet[k])) s.y_order_used = std::max(s.y_order_used, k);
  s.u_orders_used.assign(j.u.size(), 0);
  for (std::size_t q = 0; q < j.u.size(); ++q)
    for (std::size_t k = 0; k < j.u[q].size(); ++k)
      for (const auto& e : used)
        if (e.has(j.u[q][k])) s.u_orders_used[q] = std::max(s.u_orders_used[q], k);
}

Verdict applies(const Analysis& a) {
  Verdict v;
  const CanonicalForm& cf = a.canonical;
  if (a.output_transformation) {
    v.reasons.push_back(fmt::format(
        "the observer canonical form holds for psi(y) = [{}] only; the perfect observer would "
        "need the jets of psi(y(t)) (not built)",
        fmt::join(to_strings(a.output_transformation->psi), ", ")));
    return v;
  }
  if (!cf.applicable || !cf.linearizable) {
    v.reasons.push_back(
        "needs the observer canonical form (seed 003 Lemma 1): " +
        (cf.applicable ? std::string("the bracket conditions fail") : cf.not_applicable));
    return v;
  }
  if (cf.l_kind != Availability::symbolic || cf.T_kind != Availability::symbolic) {
    v.reasons.push_back("needs T and l in closed form: " +
                        (cf.T_kind != Availability::symbolic ? cf.T_note : cf.l_note));
    return v;
  }
  v.applies = true;
  set_exactness(v, cf,
                {"T and l are closed-form", "T and l are closed-form",
                 "the state is a function of the output jets",
                 "rigorous: x = T^-1(z(y, y', ..., u, ...)) exactly (brackets, T and l(u, y) "
                 "proved symbolically; exact jets assumed)",
                 "partial (numeric): the reconstruction is exact only if what is numerically "
                 "zero is zero"});
  return v;
}

GeneratedFunction jet_function(const std::string& name, const std::string& doc, const Jets& j,
                               const ExVec& out, std::size_t n, std::size_t uk) {
  GeneratedFunction f;
  f.name = name;
  f.doc = doc;
  FunctionArg yj = vector_arg("yj", "YJet", j.y_flat());
  FunctionArg uj;
  uj.kind = FunctionArg::Kind::matrix;
  uj.name = "uj";
  uj.type = "UJet";
  uj.rows = j.u.size();
  uj.cols = uk;
  for (std::size_t k = 0; k < uk; ++k)  // column-major
    for (const auto& jet : j.u) uj.symbols.push_back(jet[k]);
  f.args = {yj, uj};
  f.outputs = out;
  f.out_rows = n;
  f.out_type = "State";
  return f;
}

// T, T^-1 when it is in closed form (newton false), and the output injection l.
void add_canonical_functions(ObserverSpec& s, const Model& m, const CanonicalForm& cf,
                             bool newton) {
  const std::size_t n = m.n();
  s.functions.push_back({"T",
                         "Diffeomorphism z = T(x) to observer canonical form, T(x0) = 0.",
                         {state_arg(m)},
                         {},
                         cf.T,
                         n,
                         1,
                         "State"});
  if (!newton)
    s.functions.push_back({"T_inverse",
                           "Closed-form inverse x = T^-1(z).",
                           {vector_arg("z", "State", cf.z)},
                           {},
                           cf.T_inverse,
                           n,
                           1,
                           "State"});
  s.functions.push_back({"l",
                         "Output injection l(u, y) of the canonical form z' = A z + l(u, y).",
                         {input_arg(m), output_arg(cf.y)},
                         {},
                         cf.l,
                         n,
                         1,
                         "State"});
}

// T^-1 by runtime Newton: z from the jets, then Newton on T with the frame as inverse
// Jacobian.
void add_newton_reconstruction(ObserverSpec& s, const Model& m, const CanonicalForm& cf,
                               const Jets& j, const ExVec& z, std::size_t uk) {
  const std::size_t n = m.n();
  s.functions.push_back({"frame",
                         "Frame [tau_1 ... tau_n](x) = (dT/dx)^-1, columns tau_k.",
                         {state_arg(m)},
                         {},
                         frame_column_major(cf),
                         n,
                         n,
                         "Frame"});
  s.functions.push_back(jet_function(
      "z_of_jets", "Canonical coordinates z from the jets (Procedure 1).", j, z, n, uk));
  s.roles.reconstruct = "z_of_jets";
  s.estimate = EstimateKind::newton;
  s.roles.newton_map = "T";
  s.roles.newton_inverse_jacobian = "frame";
}

// T^-1 in closed form: z(jets), then T^-1's elimination steps, as let-bindings:
// straight-line code.
void add_closed_reconstruction(ObserverSpec& s, const Analysis& a, const Jets& j, const ExVec& z,
                               std::size_t uk) {
  const std::size_t n = a.model.n();
  GeneratedFunction inv = inverse_function(a);
  GeneratedFunction r =
      jet_function("reconstruct", "The state x = T^-1(z(jets)) from the jets (Procedure 1).", j,
                   inv.outputs, n, uk);
  for (std::size_t i = 0; i < n; ++i) r.lets.push_back({a.canonical.z[i], z[i]});
  r.lets.insert(r.lets.end(), inv.lets.begin(), inv.lets.end());
  s.functions.push_back(r);
  s.roles.reconstruct = "reconstruct";
  s.estimate = EstimateKind::identity;
}

// Description, report rows and summary: the jets used and how T^-1 is computed.
void describe_perfect(ObserverSpec& s, const Model& m, bool newton) {
  std::string u_orders;
  for (std::size_t q = 0; q < m.m(); ++q)
    u_orders +=
        fmt::format("{} (up to {}^({}))", q ? "," : "", m.inputs[q].get_name(), s.u_orders_used[q]);
  s.description.push_back(
      "Observer: perfect observer (Slawinski, seed 003 Theorem 1, Procedure 1)");
  s.description.push_back(fmt::format("Needs y up to y^({}){}", s.y_order_used,
                                      u_orders.empty() ? "" : " and the input jets" + u_orders));
  s.description.push_back(fmt::format(
      "T^-1: {}", newton ? "runtime Newton with [tau] as inverse Jacobian" : "closed form"));
  s.report = {{"jets used", fmt::format("y up to y^({}){}", s.y_order_used,
                                        u_orders.empty() ? "" : fmt::format(" and{}", u_orders))},
              {"T^-1", newton ? "by runtime Newton" : "in closed form"},
              {"differentiator time constant",
               fmt::format("constructor argument epsilon (default 0.01; simulate uses {:g})",
                           s.default_epsilon)}};
  s.summary = fmt::format("perfect observer; needs y up to y^({}){}; T^-1 {}", s.y_order_used,
                          u_orders.empty() ? "" : fmt::format(" and{}", u_orders),
                          newton ? "by runtime Newton" : "in closed form");
}

ObserverSpec build(const Analysis& a, const DesignOptions& o) {
  const Verdict v = applies(a);
  if (!v.applies) throw UserError(SourceLoc{a.model.file, 0, 0}, "method 'perfect' " + v.text());
  const Model& m = a.model;
  const CanonicalForm& cf = a.canonical;
  const std::size_t n = m.n(), uk = std::max<std::size_t>(n, 2) - 1;
  ObserverSpec s;
  s.method = "perfect";
  s.class_suffix = "Perfect";
  s.title = "Perfect observer (Slawinski, seed 003 Theorem 1, Procedure 1)";
  s.state_size = n;
  s.params = runtime_params(m);
  s.update = UpdateKind::jets;
  s.y_jet_order = n - 1;
  s.u_jet_order = uk - 1;
  if (const auto eps = real_option(o, "epsilon")) s.default_epsilon = eps->to_double();
  s.functions = model_functions(m);
  const bool newton = cf.T_inverse_kind != Availability::symbolic;
  add_canonical_functions(s, m, cf, newton);
  const Jets j = jet_symbols(m);
  const ExVec z = z_of_jets(a, j);
  if (newton)
    add_newton_reconstruction(s, m, cf, j, z, uk);
  else
    add_closed_reconstruction(s, a, j, z, uk);
  used_orders(z, j, s);
  describe_perfect(s, m, newton);
  return s;
}

}  // namespace

Design perfect_design() {
  Design d;
  d.name = "perfect";
  d.summary = "state from the jets of y and u (seed 003 Procedure 1)";
  d.options = {{"epsilon", "perfect observer: differentiator time constant", "0.01"}};
  d.plan = stateless_plan<applies, build>;
  d.observes_output_offset = false;  // differentiates y itself
  return d;
}

}  // namespace obsynth
