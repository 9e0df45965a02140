#include "app/output_dir.hpp"

#include <fmt/format.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "foundation/diagnostics.hpp"

namespace obsynth {

namespace fs = std::filesystem;

std::string staging_dir(const std::string& dir, long pid) {
  return (fs::path(dir) / fmt::format(".obsynth-staging-{}", pid)).string();
}

namespace {

[[noreturn]] void cannot_move(const fs::path& target, const std::error_code& ec) {
  throw UserError(SourceLoc{target.string(), 0, 0},
                  fmt::format("cannot move the file into place: {}", ec.message()));
}

// Moves the staged files into place as one transaction: each file the set replaces is first
// moved aside into the staging directory, and a failed move puts back every file already
// replaced (and removes the new ones), so the directory holds the old set or the new one.
void move_into_place(const fs::path& dir, const fs::path& stage,
                     const std::vector<OutputFile>& files) {
  struct Moved {
    fs::path target, backup;  // backup empty: the target did not exist before
  };
  std::vector<Moved> moved;
  std::error_code ec;
  try {
    for (std::size_t i = 0; i < files.size(); ++i) {
      const fs::path target = dir / files[i].name;
      Moved m{target, {}};
      if (fs::is_regular_file(fs::symlink_status(target, ec))) {
        m.backup = stage / fmt::format(".old-{}", i);
        fs::rename(target, m.backup, ec);
        if (ec) cannot_move(target, ec);
      }
      fs::rename(stage / files[i].name, target, ec);
      if (ec) {
        if (!m.backup.empty()) fs::rename(m.backup, target, ec);
        cannot_move(target, ec);
      }
      moved.push_back(m);
    }
  } catch (...) {
    for (auto it = moved.rbegin(); it != moved.rend(); ++it) {
      std::error_code undo;
      if (it->backup.empty())
        fs::remove(it->target, undo);
      else
        fs::rename(it->backup, it->target, undo);
    }
    throw;
  }
}

}  // namespace

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
    move_into_place(dir, stage, files);
  } catch (...) {
    fs::remove_all(stage, ec);
    throw;
  }
  fs::remove_all(stage, ec);
}

}  // namespace obsynth
