#include "front/bind.hpp"

#include <fmt/format.h>

#include "front/parse.hpp"
#include "symbolic/expr_print.hpp"

namespace obsynth {

namespace {

void bind_one(Model& m, const std::string& assignment) {
  const auto eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0)
    throw UserError(SourceLoc{}, fmt::format("--param '{}': expected name=value", assignment));
  const std::string name = assignment.substr(0, eq);
  for (auto& p : m.params) {
    if (p.name != name) continue;
    if (p.value)
      throw UserError(SourceLoc{},
                      fmt::format("--param {}: the model already gives it the value {}", name,
                                  to_string(*p.value)));
    const std::string text = assignment.substr(eq + 1);
    const GiNaC::numeric v = parse_real_number(text, fmt::format("--param {}={}", name, text));
    const auto box = m.domain.find(name);
    if (box != m.domain.end() && (v < box->second.lo || v > box->second.hi))
      throw UserError(SourceLoc{},
                      fmt::format("--param {}={}: outside its domain [{}, {}]", name, to_string(v),
                                  to_string(box->second.lo), to_string(box->second.hi)));
    const GiNaC::exmap at{{p.symbol, v}};
    for (auto* vec : {&m.f, &m.g, &m.h})
      for (auto& e : *vec) e = e.subs(at);
    p.value = v;
    m.domain.erase(name);
    return;
  }
  throw UserError(SourceLoc{},
                  fmt::format("--param {}: the model has no parameter '{}'", name, name));
}

}  // namespace

Model bind_parameters(Model m, const std::vector<std::string>& assignments) {
  for (const auto& a : assignments) bind_one(m, a);
  return m;
}

}  // namespace obsynth
