#include "designs/registry.hpp"

#include <fmt/format.h>

#include <algorithm>

#include "designs/canonical.hpp"
#include "designs/finite_time.hpp"
#include "designs/perfect.hpp"

namespace obsynth {

std::string Verdict::text() const {
  return fmt::format("{}", fmt::join(reasons, "; "));
}

const std::vector<Design>& design_registry() {
  static const std::vector<Design> designs = {
      canonical_design(),
      perfect_design(),
      finite_time_design(),
  };
  return designs;
}

const std::vector<std::string>& planned_methods() {
  static const std::vector<std::string> planned = {
      "riccati", "high-gain", "kalman-theta", "thau", "kou", "extended-linearization"};
  return planned;
}

const Design* find_design(const std::string& name) {
  for (const auto& d : design_registry())
    if (d.name == name) return &d;
  return nullptr;
}

std::vector<DesignOptionInfo> all_design_options() {
  std::vector<DesignOptionInfo> out;
  for (const auto& d : design_registry())
    for (const auto& o : d.options)
      if (std::none_of(out.begin(), out.end(), [&](const auto& q) { return q.name == o.name; }))
        out.push_back(o);
  return out;
}

}  // namespace obsynth
