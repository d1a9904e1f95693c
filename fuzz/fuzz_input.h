#pragma once
// Shared by the libFuzzer harnesses (fuzz/README.md): the fuzzer's bytes as a file for the parsers
// that read a path, and the one expected way for a parser to reject an input. An InputError is the
// parser doing its job; anything else escaping (another exception, a crash, a sanitizer report, a
// hang, a huge allocation) is a finding.

#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "core/common/error.h"

namespace marglab::fuzz {

// The input as a file. In the folder MARGLAB_FUZZ_TMP when set (fuzz/run_fuzzers.sh: one per
// target, under the build folder, given as a relative path), as "input" + suffix: a path that is
// the same in every run on every machine. The path enters the parsers' messages and comparisons,
// and through them libFuzzer's comparison-guided mutations: a name carrying the process ID made
// two runs of one build from one seed take different paths (fuzz/README.md). Without it (a
// process run by hand, or libFuzzer's -jobs running several at once), a name of its own per
// process in /dev/shm when there is one, so that the fuzzer does not wear a disk.
inline std::string writeInput(const std::uint8_t* data, std::size_t size, const char* suffix) {
  static const std::string prefix = [] {
    if (const char* dir = std::getenv("MARGLAB_FUZZ_TMP")) return std::string(dir) + "/input";
    const char* dir = access("/dev/shm", W_OK) == 0 ? "/dev/shm" : "/tmp";
    return std::string(dir) + "/marglab-fuzz-" + std::to_string(getpid());
  }();
  std::string path = prefix + suffix;
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr || std::fwrite(data, 1, size, f) != size || std::fclose(f) != 0) {
    std::perror(path.c_str());
    std::abort();  // the harness cannot run at all: not a finding in the parser
  }
  return path;
}

// Runs `parse`; an InputError is an expected outcome, everything else propagates to libFuzzer.
template <class F>
void expectInputErrorOrSuccess(F&& parse) {
  try {
    parse();
  } catch (const InputError&) {
  }
}

}  // namespace marglab::fuzz
