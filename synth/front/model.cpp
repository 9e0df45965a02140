#include "front/model.hpp"

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

GiNaC::exmap Model::nominal_inputs() const {
  GiNaC::exmap out;
  for (std::size_t i = 0; i < inputs.size(); ++i)
    out[inputs[i]] = i < nominal.size() ? GiNaC::ex(nominal[i]) : GiNaC::ex(0);
  return out;
}

}  // namespace obsynth
