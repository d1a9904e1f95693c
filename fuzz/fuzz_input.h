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

// A file named after the process (libFuzzer's -jobs runs several), rewritten for every input; in
// /dev/shm when there is one, so that the fuzzer does not wear a disk.
inline std::string writeInput(const std::uint8_t* data, std::size_t size, const char* suffix) {
  static const std::string dir = [] {
    if (const char* tmp = std::getenv("MARGLAB_FUZZ_TMP")) return std::string(tmp);
    return std::string(access("/dev/shm", W_OK) == 0 ? "/dev/shm" : "/tmp");
  }();
  std::string path = dir + "/marglab-fuzz-" + std::to_string(getpid()) + suffix;
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
