// check_summary: condenses an `obsynth check --format json` report into one tab-separated
// line for bench/run_check_bench.sh (so the script needs neither jq nor python):
//
//   <result>\t<lie ms>\t<observability ms>\t<frame ms>\t<conditions ms>\t<diffeomorphism ms>
//
// result: "linearizable", "not linearizable (C2: k/m brackets fail, C3: k/m)", or
// "rank r < n". A stage that did not run prints "-".
#include <fmt/format.h>

#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: check_summary REPORT.json\n");
    return 1;
  }
  std::ifstream in(argv[1]);
  if (!in) {
    std::fprintf(stderr, "check_summary: cannot read %s\n", argv[1]);
    return 1;
  }
  nlohmann::json j;
  try {
    in >> j;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "check_summary: %s: %s\n", argv[1], e.what());
    return 1;
  }
  const auto& ob = j.at("observability");
  const auto n = ob.at("n").get<std::size_t>();
  const auto rank = ob.at("generic_rank").get<std::size_t>();
  std::string result;
  if (rank < n) {
    result = fmt::format("rank {} < {}", rank, n);
  } else if (j.value("linearizable", false)) {
    result = "linearizable";
  } else if (!j.value("canonical_applicable", false)) {
    result = "not applicable: " + j.value("canonical_note", std::string());
  } else {
    auto failing = [](const nlohmann::json& list) {
      std::size_t bad = 0;
      for (const auto& b : list)
        if (!b.value("holds", true)) ++bad;
      return fmt::format("{}/{}", bad, list.size());
    };
    const auto& c = j.at("conditions");
    result = fmt::format("not linearizable (failing brackets: C2 {}, C3 {})",
                         failing(c.at("drift")), failing(c.at("input")));
  }
  std::string line = result;
  const auto t = j.value("timings_ms", nlohmann::json::object());
  for (const char* s : {"lie", "observability", "frame", "conditions", "diffeomorphism"})
    line += t.contains(s) ? fmt::format("\t{:.1f}", t.at(s).get<double>()) : std::string("\t-");
  std::printf("%s\n", line.c_str());
  return 0;
}
