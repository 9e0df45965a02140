#include "designs/options.hpp"

#include <fmt/format.h>

#include <algorithm>

#include "front/parse.hpp"
#include "symbolic/expr_print.hpp"

namespace obsynth {

std::vector<GiNaC::numeric> real_list_option(const DesignOptions& o, const std::string& name) {
  const std::string* text = o.find(name);
  if (!text || text->empty()) return {};
  const std::string flag = "--" + name;
  ExVec values;
  try {
    values = parse_expression_list(*text, flag, {});
  } catch (const UserError&) {
    throw UserError(
        SourceLoc{},
        fmt::format("{}: '{}' is not a comma-separated list of real numbers", flag, *text));
  }
  std::vector<GiNaC::numeric> out;
  for (const auto& v : values) {
    if (!GiNaC::is_a<GiNaC::numeric>(v) || !GiNaC::ex_to<GiNaC::numeric>(v).is_real())
      throw UserError(SourceLoc{},
                      fmt::format("{}: '{}' is not a real number", flag, to_string(v)));
    out.push_back(GiNaC::ex_to<GiNaC::numeric>(v));
  }
  return out;
}

std::optional<GiNaC::numeric> real_option(const DesignOptions& o, const std::string& name) {
  const auto v = real_list_option(o, name);
  if (v.empty()) return std::nullopt;
  if (v.size() != 1)
    throw UserError(SourceLoc{}, fmt::format("--{}: expected one number, got {}", name, v.size()));
  return v[0];
}

std::optional<std::string> choice_option(const DesignOptions& o, const std::string& name,
                                         const std::vector<std::string>& allowed) {
  const std::string* text = o.find(name);
  if (!text || text->empty()) return std::nullopt;
  if (std::find(allowed.begin(), allowed.end(), *text) == allowed.end())
    throw UserError(SourceLoc{}, fmt::format("--{}: '{}' is not one of: {}", name, *text,
                                             fmt::join(allowed, ", ")));
  return *text;
}

}  // namespace obsynth
