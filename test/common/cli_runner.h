#pragma once
// Runs the real `marglab` binary (path from test_paths.h) in a shell and
// captures its exit code and combined output, for the CLI tests of every module; or starts it in
// the background (startCli) for the tests that signal it. Also the small file helpers those
// tests share (readText, quote).

#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "test_paths.h"

namespace marglab::test {

// The whole content of a file ("" when it cannot be read).
inline std::string readText(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// A path single-quoted for a shell command line.
inline std::string quote(const std::filesystem::path& p) { return "'" + p.string() + "'"; }

struct CliResult {
  int exit_code;
  std::string output;  // stdout and stderr
};

// Runs a shell command line, capturing stdout and stderr.
inline CliResult runShell(const std::string& command_line) {
  const std::string command = command_line + " 2>&1";
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) return {-1, "popen failed"};
  std::string output;
  char buffer[4096];
  while (fgets(buffer, sizeof(buffer), pipe) != nullptr) output += buffer;
  const int status = pclose(pipe);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, output};
}

inline CliResult runCli(const std::string& args) {
  return runShell(std::string("'") + test::cliPath() + "' " + args);
}

// Starts the CLI in the background; stdout and stderr go to `log`.
inline pid_t startCli(const std::vector<std::string>& args, const std::string& log) {
  const pid_t pid = fork();
  if (pid == 0) {
    const int fd = open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    dup2(fd, 1);
    dup2(fd, 2);
    std::vector<char*> argv;
    std::vector<std::string> all = {test::cliPath()};
    all.insert(all.end(), args.begin(), args.end());
    for (auto& a : all) argv.push_back(a.data());
    argv.push_back(nullptr);
    execv(argv[0], argv.data());
    _exit(127);
  }
  return pid;
}

// The first interpreter among /usr/bin/python3 and `python3` on PATH that imports h5py and numpy;
// empty if none does.
inline std::string findPythonWithH5py() {
  for (const std::string candidate : {"/usr/bin/python3", "python3"}) {
    const std::string command = candidate + " -c 'import h5py, numpy' > /dev/null 2>&1";
    if (std::system(command.c_str()) == 0) return candidate;
  }
  return {};
}

}  // namespace marglab::test
