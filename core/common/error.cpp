#include "core/common/error.h"

namespace marglab {
namespace {
std::string formatLocation(const std::string& file, int line, const std::string& what) {
  if (line > 0) return file + ":" + std::to_string(line) + ": " + what;
  if (file.empty()) return what;
  return file + ": " + what;
}

std::string describe(const Problem& p) {
  return p.kind == ProblemKind::kUsage ? p.message : formatLocation(p.file, p.line, p.message);
}
}  // namespace

InputError::InputError(std::string file, int line, const std::string& what)
    : std::runtime_error(formatLocation(file, line, what)),
      file_(std::move(file)),
      line_(line),
      detail_(what) {}

std::string shortToken(std::string_view token, std::size_t max_chars) {
  if (token.size() <= max_chars) return std::string(token);
  std::size_t cut = max_chars;
  while (cut > 0 && (static_cast<unsigned char>(token[cut]) & 0xC0) == 0x80) --cut;
  return std::string(token.substr(0, cut)) + "… (" + std::to_string(token.size()) + " bytes)";
}

void throwProblems(const std::vector<Problem>& problems) {
  const Problem& first = problems.front();
  std::string more;
  for (std::size_t i = 1; i < problems.size(); ++i) more += "\n  also: " + describe(problems[i]);
  if (first.kind == ProblemKind::kUsage) throw UsageError(first.message + more);
  throw InputError(first.file, first.line, first.message + more);
}

}  // namespace marglab
