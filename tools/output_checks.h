#pragma once
// Outputs checked before any work (docs/design.md §7).
//
// An output never replaces an input of the same command: `run --dataset K/sequences/06
// -o K/poses/06.txt` would otherwise write HDF5 over the ground truth it reads. Every output path
// (a results file, its TUM trajectory, a track file, a sweep's index) is refused (InputError,
// exit 1, naming both paths) when it is the same file as an input (same device and inode:
// symbolic and hard links included), or when it lies inside an input folder (a dataset folder,
// the shipped datasets: every file in them counts as data) whether or not it exists yet.
//
// An output is also refused when it exists and is a device node, a FIFO or a socket: outputs are
// written to a temporary and renamed onto their path (core/common/atomic_file.h), which would
// replace the node with a regular file.

#include <filesystem>
#include <string>
#include <vector>

namespace marglab::cli {

struct CommandInputs {
  std::vector<std::string> files;    // e.g. --config, --tracks, a dataset's files ("" ignored)
  std::vector<std::string> folders;  // e.g. the dataset folder, the shipped datasets
};

// What a dataset argument reads: the folders (its own when it is a folder, and the shipped
// datasets: names, calibrations, the ground truth an image folder falls back to) and the files
// it is loaded from wherever they lie (KITTI's official dataset/poses/NN.txt beside the
// sequences, a shipped-layout folder's ../calib/).
CommandInputs datasetInputs(const std::string& dataset);

// Appends `more` to `inputs`.
void addInputs(CommandInputs* inputs, const CommandInputs& more);

// Whether `file` (which need not exist) lies inside the existing `folder`, after resolving
// symbolic links and "..".
bool isInsideFolder(const std::filesystem::path& file, const std::filesystem::path& folder);

// Throws InputError naming the output and the input it would replace (above).
void refuseOverwritingInputs(const std::vector<std::string>& outputs, const CommandInputs& inputs);

// An output file checked before any work (a run must not track or estimate for minutes and then
// find it cannot write): not "", not a folder, not a device node / FIFO / socket, in an existing
// folder this process may write. Throws UsageError for "" and InputError naming the path and
// what was expected otherwise.
void checkOutputFile(const std::string& output, const std::string& option);

}  // namespace marglab::cli
