#pragma once
// A fresh folder per test, removed at the end of it: named after the process and the test ('/' of
// parameterized names replaced), so that parallel ctest processes never share one (a process runs
// its tests one after the other). TempDirTest is the fixture base of tests that keep their
// files in it (dir_).

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>

namespace marglab::test {

class TempDir {
 public:
  TempDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    std::string name = info->name();
    for (char& c : name) {
      if (c == '/') c = '_';
    }
    path_ = std::filesystem::temp_directory_path() /
            ("marglab_" + std::to_string(::getpid()) + "_" + name);
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  std::string file(const std::string& name) const { return (path_ / name).string(); }
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

class TempDirTest : public ::testing::Test {
 protected:
  TempDir temp_;
  const std::filesystem::path& dir_ = temp_.path();
};

}  // namespace marglab::test
