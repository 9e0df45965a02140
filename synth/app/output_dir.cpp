#include "app/output_dir.hpp"

#include <fmt/format.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "front/diagnostics.hpp"

namespace obsynth {

namespace fs = std::filesystem;

std::string staging_dir(const std::string& dir, long pid) {
  return (fs::path(dir) / fmt::format(".obsynth-staging-{}", pid)).string();
}

void write_output_dir(const std::string& dir, const std::vector<OutputFile>& files) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec)
    throw UserError(SourceLoc{dir, 0, 0},
                    fmt::format("cannot create the output directory: {}", ec.message()));
  const fs::path stage = staging_dir(dir, static_cast<long>(getpid()));
  fs::remove_all(stage, ec);
  fs::create_directory(stage, ec);
  if (ec)
    throw UserError(SourceLoc{dir, 0, 0},
                    fmt::format("cannot write into the output directory: {}", ec.message()));
  try {
    for (const auto& f : files) {
      std::ofstream out(stage / f.name, std::ios::binary);
      out << f.content;
      out.close();
      if (!out)
        throw UserError(SourceLoc{(fs::path(dir) / f.name).string(), 0, 0},
                        "cannot write the file");
    }
    for (const auto& f : files) {
      fs::rename(stage / f.name, fs::path(dir) / f.name, ec);
      if (ec)
        throw UserError(SourceLoc{(fs::path(dir) / f.name).string(), 0, 0},
                        fmt::format("cannot move the file into place: {}", ec.message()));
    }
  } catch (...) {
    fs::remove_all(stage, ec);
    throw;
  }
  fs::remove_all(stage, ec);
}

}  // namespace obsynth
