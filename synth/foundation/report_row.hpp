// One row of a report's table: a key and its text (designs, certificates and the report
// renderers share it).
#pragma once

#include <string>

namespace obsynth {

struct ReportRow {
  std::string key, value;
};

}  // namespace obsynth
