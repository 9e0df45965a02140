// Atomic writing of a set of files into an output directory: everything is written into a
// staging directory next to the targets and renamed into place only when all files are
// complete, so a failure never leaves half-written files in the output directory.
#pragma once

#include <string>
#include <utility>
#include <vector>

namespace obsynth {

struct OutputFile {
  std::string name;  // file name inside the directory
  std::string content;
};

// Throws UserError when the directory cannot be created or written.
void write_output_dir(const std::string& dir, const std::vector<OutputFile>& files);

// The staging directory a process with this pid would use (for cleanup after a kill).
std::string staging_dir(const std::string& dir, long pid);

}  // namespace obsynth
