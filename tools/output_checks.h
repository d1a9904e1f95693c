#pragma once
// Outputs never replace an input of the same command (docs/design.md §7): `run --dataset SEQ
// -o SEQ/poses.txt` would otherwise write HDF5 over the poses it reads. An output that already
// exists is refused (InputError, exit 1, naming both) when it is the same file as an input (same
// device and inode: symbolic and hard links included) or lies inside an input folder (a dataset
// folder: every file in it counts as data). An output that does not exist yet replaces nothing.

#include <fmt/core.h>
#include <unistd.h>

#include <filesystem>
#include <string>
#include <vector>

#include "core/common/error.h"
#include "core/data/sequence.h"

namespace marglab::cli {

struct CommandInputs {
  std::vector<std::string> files;    // e.g. --config, --tracks ("" entries are ignored)
  std::vector<std::string> folders;  // e.g. the dataset folder
};

// The folders a dataset argument reads from: the folder itself, and the shipped data (names, and
// the shipped files a folder may fall back to).
inline std::vector<std::string> datasetInputFolders(const std::string& dataset) {
  std::vector<std::string> folders{datasetsRoot()};
  if (std::filesystem::is_directory(dataset)) folders.push_back(dataset);
  return folders;
}

inline bool isInsideFolder(const std::filesystem::path& file, const std::filesystem::path& folder) {
  std::error_code ec;
  const std::filesystem::path f = std::filesystem::canonical(file, ec);
  if (ec) return false;
  const std::filesystem::path d = std::filesystem::canonical(folder, ec);
  if (ec) return false;
  auto fi = f.begin();
  for (auto di = d.begin(); di != d.end(); ++di, ++fi) {
    if (fi == f.end() || *fi != *di) return false;
  }
  return fi != f.end();
}

inline void refuseOverwritingInputs(const std::vector<std::string>& outputs,
                                    const CommandInputs& inputs) {
  namespace fs = std::filesystem;
  for (const std::string& output : outputs) {
    std::error_code ec;
    if (output.empty() || !fs::exists(output, ec)) continue;
    for (const std::string& input : inputs.files) {
      if (!input.empty() && fs::equivalent(output, input, ec)) {
        throw InputError(output, 0,
                         fmt::format("this output is {}, an input of this command: write the "
                                     "output elsewhere",
                                     input));
      }
    }
    for (const std::string& folder : inputs.folders) {
      if (isInsideFolder(output, folder)) {
        throw InputError(output, 0,
                         fmt::format("this output would replace a file in {}, an input folder "
                                     "(dataset) of this command: write the output elsewhere",
                                     folder));
      }
    }
  }
}

// An output file checked before any work (a run must not track or estimate for minutes and then
// find it cannot write): not "", not a folder, in an existing folder this process may write.
// Throws UsageError for "" and InputError naming the path and what was expected otherwise.
inline void checkOutputFile(const std::string& output, const std::string& option) {
  namespace fs = std::filesystem;
  if (output.empty()) throw UsageError(option + " is empty: expected the path of a file to write");
  std::error_code ec;
  if (fs::is_directory(output, ec)) {
    throw InputError(output, 0, "is a folder: expected the path of a file to write (" + option +
                                    ")");
  }
  const fs::path parent = fs::absolute(output, ec).parent_path();
  if (!fs::is_directory(parent, ec)) {
    throw InputError(parent.string(), 0,
                     "no such folder: expected the folder of " + option + " to exist");
  }
  if (::access(parent.c_str(), W_OK) != 0) {
    throw InputError(parent.string(), 0,
                     "not writable: cannot write " + option + " " + output + " there");
  }
}

}  // namespace marglab::cli
