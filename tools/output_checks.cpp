#include "tools/output_checks.h"

#include <fmt/core.h>
#include <unistd.h>

#include "core/common/atomic_file.h"
#include "core/common/error.h"
#include "core/data/sequence.h"

namespace marglab::cli {

namespace fs = std::filesystem;

namespace {

// "mav0/cam{0,1}/sensor.yaml" (Sequence::calib_source) → both files.
std::vector<std::string> expandCameraPattern(const std::string& source) {
  const std::string pattern = "{0,1}";
  const std::size_t at = source.find(pattern);
  if (at == std::string::npos) return {source};
  std::string cam0 = source, cam1 = source;
  return {cam0.replace(at, pattern.size(), "0"), cam1.replace(at, pattern.size(), "1")};
}

// The path with symbolic links and ".." resolved as far as it exists (the rest lexically).
fs::path resolved(const fs::path& path) {
  std::error_code ec;
  const fs::path r = fs::weakly_canonical(fs::absolute(path, ec), ec);
  return ec ? fs::absolute(path).lexically_normal() : r;
}

void refuseSameFile(const std::string& output, const CommandInputs& inputs) {
  std::error_code ec;
  if (!fs::exists(output, ec)) return;
  for (const std::string& input : inputs.files) {
    if (!input.empty() && fs::equivalent(output, input, ec)) {
      throw InputError(output, 0,
                       fmt::format("this output is {}, an input of this command: write the "
                                   "output elsewhere",
                                   input));
    }
  }
}

void refuseInsideInputFolder(const std::string& output, const CommandInputs& inputs) {
  for (const std::string& folder : inputs.folders) {
    if (isInsideFolder(output, folder)) {
      throw InputError(output, 0,
                       fmt::format("this output lies in {}, an input folder (dataset) of this "
                                   "command: write the output elsewhere",
                                   folder));
    }
  }
}

}  // namespace

CommandInputs datasetInputs(const std::string& dataset) {
  CommandInputs inputs{{}, {datasetsRoot()}};
  std::error_code ec;
  if (fs::is_directory(dataset, ec)) inputs.folders.push_back(dataset);
  try {
    const Sequence seq = loadSequence(dataset, LoadOptions{false});
    inputs.files = {seq.gt_file, seq.cam_file, seq.imu_file};
    for (const std::string& calib : expandCameraPattern(seq.calib_source)) {
      inputs.files.push_back(calib);
    }
  } catch (const InputError&) {
    // A dataset that does not load fails in the command's own load, before any output is
    // written; its folders are still inputs.
  }
  return inputs;
}

void addInputs(CommandInputs* inputs, const CommandInputs& more) {
  inputs->files.insert(inputs->files.end(), more.files.begin(), more.files.end());
  inputs->folders.insert(inputs->folders.end(), more.folders.begin(), more.folders.end());
}

bool isInsideFolder(const fs::path& file, const fs::path& folder) {
  std::error_code ec;
  if (!fs::is_directory(folder, ec)) return false;
  const fs::path f = resolved(file);
  const fs::path d = fs::canonical(folder, ec);
  if (ec) return false;
  auto fi = f.begin();
  for (auto di = d.begin(); di != d.end(); ++di, ++fi) {
    if (fi == f.end() || *fi != *di) return false;
  }
  return fi != f.end();
}

void refuseOverwritingInputs(const std::vector<std::string>& outputs, const CommandInputs& inputs) {
  for (const std::string& output : outputs) {
    if (output.empty()) continue;
    refuseSameFile(output, inputs);
    refuseInsideInputFolder(output, inputs);
  }
}

void checkOutputFile(const std::string& output, const std::string& option) {
  if (output.empty()) throw UsageError(option + " is empty: expected the path of a file to write");
  std::error_code ec;
  if (fs::is_directory(output, ec)) {
    throw InputError(output, 0,
                     "is a folder: expected the path of a file to write (" + option + ")");
  }
  refuseSpecialFileOutput(output);
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
