#include "designs/spec.hpp"

#include <fmt/format.h>

#include <cctype>
#include <map>
#include <set>
#include <utility>

#include "symbolic/expr_print.hpp"

namespace obsynth {

std::size_t SymmetricBlock::packed_index(std::size_t r, std::size_t c) const {
  if (r > c) std::swap(r, c);
  // Rows 0..r-1 hold dim, dim-1, ..., dim-r+1 entries.
  return offset + r * dim - r * (r - 1) / 2 + (c - r);
}

std::size_t ConstTable::size() const {
  std::size_t k = 1;
  for (auto d : dims) k *= d;
  return k;
}

std::size_t SampledDelay::points() const {
  std::size_t k = 1;
  for (auto c : grid_count) k *= c;
  return k;
}

const ConstTable* ObserverSpec::table(const std::string& name) const {
  for (const auto& t : tables)
    if (t.name == name) return &t;
  return nullptr;
}

const GeneratedFunction* ObserverSpec::function(const std::string& name) const {
  for (const auto& f : functions)
    if (f.name == name) return &f;
  return nullptr;
}

FunctionArg vector_arg(const std::string& name, const std::string& type,
                       const std::vector<GiNaC::symbol>& symbols, FunctionArg::Kind kind) {
  FunctionArg a;
  a.kind = kind;
  a.name = name;
  a.type = type;
  a.symbols = symbols;
  a.rows = symbols.size();
  return a;
}

FunctionArg state_arg(const Model& m, const std::string& name) {
  return vector_arg(name, "State", m.states, FunctionArg::Kind::state);
}

FunctionArg input_arg(const Model& m) {
  return vector_arg("u", "Input", m.inputs, FunctionArg::Kind::input);
}

FunctionArg output_arg(const std::vector<GiNaC::symbol>& y) {
  return vector_arg("y", "Output", y, FunctionArg::Kind::output);
}

namespace {

GeneratedFunction map_function(const std::string& name, const std::string& doc,
                               std::vector<FunctionArg> args, const ExVec& out,
                               const std::string& out_type) {
  GeneratedFunction f;
  f.name = name;
  f.doc = doc;
  f.args = std::move(args);
  f.outputs = out;
  f.out_rows = out.size();
  f.out_type = out_type;
  return f;
}

}  // namespace

std::vector<GeneratedFunction> model_functions(const Model& m) {
  return {map_function("f", "Drift f(x).", {state_arg(m)}, m.f, "State"),
          map_function("g", "Input part g(x, u), zero at u = 0.", {state_arg(m), input_arg(m)}, m.g,
                       "State"),
          m.feedthrough() ? map_function("h", "Output map h(x, u) (direct feedthrough).",
                                         {state_arg(m), input_arg(m)}, m.h, "Output")
                          : map_function("h", "Output map h(x).", {state_arg(m)}, m.h, "Output")};
}

std::vector<RuntimeParam> runtime_params(const Model& m) {
  std::vector<RuntimeParam> out;
  for (const auto& s : m.free_params()) {
    const Interval b = m.box(s);
    RuntimeParam p;
    p.symbol = s;
    p.name = s.get_name();
    p.default_value = (b.lo + b.hi) / 2;
    p.default_reason = fmt::format("centre of its box [{}, {}]", to_string(b.lo), to_string(b.hi));
    out.push_back(p);
  }
  return out;
}

std::vector<std::pair<GiNaC::symbol, GiNaC::ex>> let_pairs(const GeneratedFunction& f) {
  std::vector<std::pair<GiNaC::symbol, GiNaC::ex>> out;
  for (const auto& l : f.lets) out.emplace_back(l.symbol, l.value);
  return out;
}

bool outputs_carry_nonfinite(const GeneratedFunction& f, std::size_t arg) {
  if (arg >= f.args.size() || f.args[arg].symbols.empty()) return false;
  const FunctionArg* a = &f.args[arg];
  // The argument's symbols and the lets that depend on them, each a variable of the polynomial
  // test; `reaches` maps every such variable to the argument components it depends on.
  GiNaC::lst variables;
  std::map<GiNaC::ex, std::set<std::size_t>, GiNaC::ex_is_less> reaches;
  for (std::size_t i = 0; i < a->symbols.size(); ++i) {
    variables.append(a->symbols[i]);
    reaches[a->symbols[i]] = {i};
  }
  auto polynomial = [&](const GiNaC::ex& e) {
    for (const auto& v : variables)
      if (!e.is_polynomial(v)) return false;
    return true;
  };
  auto components_of = [&](const GiNaC::ex& e) {
    std::set<std::size_t> out;
    for (const auto& [v, comps] : reaches)
      if (e.has(v)) out.insert(comps.begin(), comps.end());
    return out;
  };
  for (const auto& l : f.lets) {
    const std::set<std::size_t> comps = components_of(l.value);
    if (comps.empty()) continue;
    if (!polynomial(l.value)) return false;
    variables.append(l.symbol);
    reaches[l.symbol] = comps;
  }
  std::set<std::size_t> reached;
  for (const auto& out : f.outputs) {
    const std::set<std::size_t> comps = components_of(out);
    if (!comps.empty() && !polynomial(out)) return false;
    reached.insert(comps.begin(), comps.end());
  }
  return reached.size() == a->symbols.size();
}

bool estimate_shows_nonfinite_state(const ObserverSpec& s) {
  if (s.estimate != EstimateKind::function) return false;
  const GeneratedFunction* estimate = s.function(s.roles.estimate);
  return estimate && outputs_carry_nonfinite(*estimate, 0);
}

std::string pascal_case(const std::string& name) {
  std::string out;
  bool up = true;
  for (char c : name) {
    if (c == '_') {
      up = true;
      continue;
    }
    out += up ? static_cast<char>(std::toupper(static_cast<unsigned char>(c))) : c;
    up = false;
  }
  return out;
}

}  // namespace obsynth
