#pragma once
// Helpers of the data-loader tests: the per-test temporary folder (common/temp_dir.h), fixture
// writers (plain and gzip) and an InputError matcher that checks the file, the line and the text.

#include <gtest/gtest.h>
#include <unistd.h>
#include <zlib.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "common/temp_dir.h"
#include "core/common/error.h"

namespace marglab::test {

namespace fs = std::filesystem;

inline std::string writeFile(const std::string& path, const std::string& text) {
  fs::create_directories(fs::path(path).parent_path());
  std::ofstream out(path, std::ios::binary);
  out << text;
  return path;
}

inline std::string writeGz(const std::string& path, const std::string& text) {
  fs::create_directories(fs::path(path).parent_path());
  gzFile gz = gzopen(path.c_str(), "wb9");
  gzwrite(gz, text.data(), static_cast<unsigned>(text.size()));
  gzclose(gz);
  return path;
}

inline std::string readGz(const std::string& path) {
  gzFile gz = gzopen(path.c_str(), "rb");
  std::string text;
  char buffer[1 << 16];
  int n = 0;
  while ((n = gzread(gz, buffer, sizeof(buffer))) > 0) text.append(buffer, n);
  gzclose(gz);
  return text;
}

// Runs f and expects InputError(file, line) whose message holds "FILE:LINE:" and `fragment`.
template <typename F>
void expectInputError(F&& f, const std::string& file, int line, const std::string& fragment) {
  try {
    f();
    ADD_FAILURE() << "expected InputError for " << file << ":" << line;
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_EQ(e.file(), file) << what;
    EXPECT_EQ(e.line(), line) << what;
    const std::string location = line > 0 ? file + ":" + std::to_string(line) + ": " : file + ": ";
    EXPECT_EQ(what.rfind(location, 0), 0u) << what;
    EXPECT_NE(what.find(fragment), std::string::npos) << what;
  }
}

}  // namespace marglab::test
