// gen_family: writes the benchmark model families as .sym files.
//
//   gen_family OUT_DIR                       all families at their sizes (family_sizes:
//                                            2, 4, 8, 12, 16; nested and dense 2..16)
//   gen_family OUT_DIR FAMILY N [N ...]      one family, the given sizes
//   gen_family --print FAMILY N              the text on stdout
//
// Files are <family>_n<N>.sym; an unchanged file is not rewritten (keeps timestamps stable).
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "families.hpp"

namespace fs = std::filesystem;
using namespace obsynth::bench;

namespace {

int usage() {
  std::fprintf(stderr,
               "usage: gen_family OUT_DIR [FAMILY N...]\n"
               "       gen_family --print FAMILY N\n"
               "families: chain, cubic, sine, nested, dense\n");
  return 1;
}

bool write_if_changed(const fs::path& path, const std::string& text) {
  {
    std::ifstream in(path, std::ios::binary);
    if (in) {
      std::ostringstream old;
      old << in.rdbuf();
      if (old.str() == text) return true;
    }
  }
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << text;
  return static_cast<bool>(out);
}

bool parse_size(const char* s, int& n) {
  char* end = nullptr;
  const long v = std::strtol(s, &end, 10);
  if (!end || *end != '\0' || v < 2 || v > 64) return false;
  n = static_cast<int>(v);
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) return usage();
  const std::string first = argv[1];
  if (first == "--help" || first == "-h") {
    usage();
    return 0;
  }
  if (first == "--print") {
    int n = 0;
    if (argc != 4 || !parse_family(argv[2]) || !parse_size(argv[3], n)) return usage();
    std::cout << family_model(*parse_family(argv[2]), n);
    return 0;
  }
  std::vector<Family> families = all_families();
  std::vector<int> sizes;  // empty: each family's own sizes
  if (argc >= 3) {
    const auto f = parse_family(argv[2]);
    if (!f) {
      std::fprintf(stderr, "gen_family: unknown family '%s'\n", argv[2]);
      return usage();
    }
    families = {*f};
    if (argc >= 4) {
      sizes.clear();
      for (int i = 3; i < argc; ++i) {
        int n = 0;
        if (!parse_size(argv[i], n)) {
          std::fprintf(stderr, "gen_family: bad size '%s' (2..64)\n", argv[i]);
          return usage();
        }
        sizes.push_back(n);
      }
    }
  }
  const fs::path dir = first;
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) {
    std::fprintf(stderr, "gen_family: cannot create %s: %s\n", dir.c_str(), ec.message().c_str());
    return 1;
  }
  for (Family f : families)
    for (int n : sizes.empty() ? family_sizes(f) : sizes) {
      const fs::path p = dir / model_file_name(f, n);
      if (!write_if_changed(p, family_model(f, n))) {
        std::fprintf(stderr, "gen_family: cannot write %s\n", p.c_str());
        return 1;
      }
    }
  return 0;
}
