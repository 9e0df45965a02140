// Reports of an analysis: JSON (the machine interface; every expression a string that
// GiNaC's parser reads back to the same expression), text for the terminal, markdown and
// LaTeX ready to paste.
#pragma once

#include <nlohmann/json.hpp>

#include <string>

#include "analysis/analysis.hpp"

namespace obsynth {

enum class ReportFormat { text, json, markdown, latex };

struct ReportOptions {
  bool timings = true;  // include timings_ms values (they differ between runs)
};

nlohmann::ordered_json report_json(const Analysis& a, const ReportOptions& opt = {});
// Plain text escaped for LaTeX.
std::string latex_text(const std::string& t);

std::string render_report(const Analysis& a, ReportFormat format, const ReportOptions& opt = {});

}  // namespace obsynth
