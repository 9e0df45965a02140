#include "foundation/diagnostics.hpp"

#include <fmt/format.h>

namespace obsynth {

namespace {
const char* severity_name(Severity s) {
  switch (s) {
    case Severity::error:
      return "error";
    case Severity::warning:
      return "warning";
    case Severity::note:
      return "note";
  }
  return "error";
}

std::string join_messages(const std::vector<Diagnostic>& diags) {
  std::string out;
  for (const auto& d : diags) {
    if (!out.empty()) out += '\n';
    out += format_diagnostic(d);
  }
  return out;
}
}  // namespace

std::string format_diagnostic(const Diagnostic& d) {
  std::string where;
  if (!d.loc.file.empty()) where = d.loc.file + ":";
  if (d.loc.line > 0) where += fmt::format("{}:{}:", d.loc.line, d.loc.col);
  if (!where.empty()) where += ' ';
  return fmt::format("{}{}: {}", where, severity_name(d.severity), d.message);
}

UserError::UserError(std::vector<Diagnostic> diags)
    : std::runtime_error(join_messages(diags)), diags_(std::move(diags)) {}

UserError::UserError(SourceLoc loc, const std::string& message)
    : UserError(std::vector<Diagnostic>{Diagnostic{Severity::error, std::move(loc), message}}) {}

void internal_assert_failed(const char* cond, const char* file, int line, const std::string& msg) {
  throw InternalError(
      fmt::format("internal error: {} ({}:{}: assertion '{}' failed)", msg, file, line, cond));
}

}  // namespace obsynth
