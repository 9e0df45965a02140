#include "front/model.hpp"

#include <fmt/format.h>

#include "front/fresh_names.hpp"

namespace obsynth {

std::vector<GiNaC::symbol> Model::free_params() const {
  std::vector<GiNaC::symbol> out;
  for (const auto& p : params)
    if (!p.value) out.push_back(p.symbol);
  return out;
}

std::vector<GiNaC::symbol> Model::all_symbols() const {
  std::vector<GiNaC::symbol> out(states);
  out.insert(out.end(), inputs.begin(), inputs.end());
  for (const auto& p : free_params()) out.push_back(p);
  return out;
}

Interval Model::box(const GiNaC::symbol& s) const {
  auto it = domain.find(s.get_name());
  if (it != domain.end()) return it->second;
  for (const auto& p : params)
    if (p.symbol == s) return {GiNaC::numeric(1, 2), GiNaC::numeric(2)};
  return {GiNaC::numeric(-2), GiNaC::numeric(2)};
}

SampleBoxes Model::sample_boxes() const {
  SampleBoxes b;
  for (const auto& s : all_symbols()) b.by_name[s.get_name()] = box(s);
  return b;
}

ExVec Model::field() const {
  ExVec out(f.size());
  for (std::size_t i = 0; i < f.size(); ++i) out[i] = f[i] + g[i];
  return out;
}

bool Model::feedthrough() const {
  for (const auto& e : h)
    for (const auto& u : inputs)
      if (e.has(u)) return true;
  return false;
}

ExVec Model::measured_outputs() const {
  ExVec y = h;
  for (std::size_t i = 0; i < output_offset.size() && i < y.size(); ++i) y[i] += output_offset[i];
  return y;
}

GiNaC::exmap Model::nominal_inputs() const {
  GiNaC::exmap out;
  for (std::size_t i = 0; i < inputs.size(); ++i)
    out[inputs[i]] = i < nominal.size() ? GiNaC::ex(nominal[i]) : GiNaC::ex(0);
  return out;
}

// fresh_names.hpp

bool has_name(const Model& m, const std::string& name) {
  for (const auto* list : {&m.states, &m.inputs})
    for (const auto& s : *list)
      if (s.get_name() == name) return true;
  for (const auto& p : m.params)
    if (p.name == name || p.symbol.get_name() == name) return true;
  return false;
}

GiNaC::symbol fresh_symbol(const Model& m, std::string stem) {
  while (has_name(m, stem)) stem += "_";
  return GiNaC::symbol(stem);
}

std::vector<GiNaC::symbol> fresh_symbols(const Model& m, std::string stem, std::size_t count,
                                         std::size_t first) {
  const auto taken = [&](const std::string& s) {
    for (std::size_t k = first; k < first + count; ++k)
      if (has_name(m, fmt::format("{}{}", s, k))) return true;
    return false;
  };
  while (taken(stem)) stem += "_";
  std::vector<GiNaC::symbol> out;
  for (std::size_t k = first; k < first + count; ++k)
    out.emplace_back(fmt::format("{}{}", stem, k));
  return out;
}

std::vector<GiNaC::symbol> measurement_symbols(const Model& m) {
  if (m.p() == 1) return {fresh_symbol(m, "y")};
  return fresh_symbols(m, "y", m.p());
}

}  // namespace obsynth
