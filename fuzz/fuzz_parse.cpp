// libFuzzer target for the .sym front end (design.md §2, §5 "Front end").
//
// Feeds arbitrary bytes to obsynth::parse_model. The only acceptable outcomes are a Model or
// an obsynth::UserError carrying at least one positioned diagnostic. Anything else is a
// finding: another exception type escaping (InternalError, GiNaC/CLN/std exceptions), a crash,
// a sanitizer report, a leak, a timeout or running out of memory.
//
// Build and run with fuzz/build_and_run.sh (clang++, -fsanitize=fuzzer,address,undefined).

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>
#include <string_view>

#include "foundation/diagnostics.hpp"
#include "front/parse.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  try {
    const obsynth::Model m = obsynth::parse_model(text, "fuzz.sym");
    // A successful parse must be internally consistent.
    if (m.f.size() != m.n() || m.g.size() != m.n() || m.h.empty() || m.name.empty()) {
      std::fprintf(stderr, "fuzz_parse: inconsistent model (n=%zu |f|=%zu |g|=%zu |h|=%zu)\n",
                   m.n(), m.f.size(), m.g.size(), m.h.size());
      std::abort();
    }
  } catch (const obsynth::UserError& e) {
    // Expected for most inputs, but every diagnostic must be well formed.
    if (e.diagnostics().empty()) {
      std::fprintf(stderr, "fuzz_parse: UserError without diagnostics\n");
      std::abort();
    }
    const long lines = 1 + std::count(text.begin(), text.end(), '\n');
    for (const auto& d : e.diagnostics()) {
      if (d.loc.line < 1 || d.loc.line > lines || d.loc.col < 1 || d.message.empty()) {
        std::fprintf(stderr, "fuzz_parse: bad diagnostic: %s\n",
                     obsynth::format_diagnostic(d).c_str());
        std::abort();
      }
    }
  }
  // Any other exception propagates out of this function: libFuzzer reports it as a crash
  // (uncaught exception -> std::terminate -> abort), which is what we want.
  return 0;
}
