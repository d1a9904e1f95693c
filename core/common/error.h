#pragma once
// Errors for bad input. InputError carries the file and line it refers to, so that every loader
// and config reader reports "FILE:LINE: what was expected"; the CLI maps it to exit code 1.

#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace marglab {

class InputError : public std::runtime_error {
 public:
  // line 0 means "the file as a whole" (missing file, empty file, ...); an empty file means the
  // error is about no file (what() is then `what` alone).
  InputError(std::string file, int line, const std::string& what);
  const std::string& file() const { return file_; }
  int line() const { return line_; }
  // The message without "FILE:LINE: ", for re-throwing with a better location.
  const std::string& detail() const { return detail_; }

 private:
  std::string file_;
  int line_;
  std::string detail_;
};

// A token from the input as echoed in a message: at most `max_chars` bytes (cut at a UTF-8
// character boundary) followed by "…" and the full length, so that a 5 MB garbage field does not
// become a 5 MB error message.
std::string shortToken(std::string_view token, std::size_t max_chars = 80);

// A command-line usage error (unknown variant, bad option value): exit code 2.
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// One thing wrong with a run's input: a usage error (a command-line option; `message` names it)
// or an input error at a file and line (empty file: about no file). Validators collect every
// problem, then throwProblems reports them together.
enum class ProblemKind { kUsage, kInput };
struct Problem {
  ProblemKind kind = ProblemKind::kInput;
  std::string file;
  int line = 0;
  std::string message;
};

// Throws for problems.front() — UsageError(message), or InputError(file, line, message) — with
// every further problem on its own line ("  also: ..."). Precondition: !problems.empty().
[[noreturn]] void throwProblems(const std::vector<Problem>& problems);

}  // namespace marglab
