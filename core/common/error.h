#pragma once
// Errors for bad input. InputError carries the file and line it refers to, so that every loader
// and config reader reports "FILE:LINE: what was expected"; the CLI maps it to exit code 1.

#include <stdexcept>
#include <string>

namespace marglab {

class InputError : public std::runtime_error {
 public:
  // line 0 means "the file as a whole" (missing file, empty file, ...).
  InputError(std::string file, int line, const std::string& what);
  const std::string& file() const { return file_; }
  int line() const { return line_; }

 private:
  std::string file_;
  int line_;
};

// A command-line usage error (unknown variant, bad option value): exit code 2.
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace marglab
