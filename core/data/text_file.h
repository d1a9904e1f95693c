#pragma once
// Line reader for the dataset text files, plain or gzip-compressed (zlib's gzopen/gzgets read both
// transparently), and strict field parsers. Every failure throws InputError(file, line, "expected
// …") with the 1-based line number of the raw file, so a user can open the file at that line.
//
// Lines: CR before LF is stripped (EuRoC IMU files use CRLF); blank lines and lines whose first
// non-blank character is '#' are skipped by nextDataLine().

#include <zlib.h>

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace marglab {

class TextFile {
 public:
  // Throws InputError(path, 0, …) when the file does not exist or cannot be read.
  explicit TextFile(std::string path);
  ~TextFile();
  TextFile(const TextFile&) = delete;
  TextFile& operator=(const TextFile&) = delete;

  // The next raw line (CR stripped); false at end of file.
  bool nextLine(std::string_view& line);
  // The next line that is neither blank nor a '#' comment, trimmed; false at end of file.
  bool nextDataLine(std::string_view& line);

  const std::string& path() const { return path_; }
  int lineNumber() const { return line_; }
  // Throws InputError(path, current line, expected).
  [[noreturn]] void fail(const std::string& expected) const;

 private:
  std::string path_;
  gzFile file_ = nullptr;
  std::string buffer_;
  int line_ = 0;
};

// Splits at any of `separators`, trimming blanks around each field. With whitespace separators
// (" \t") runs of separators count as one; with "," every comma starts a new (possibly empty)
// field.
std::vector<std::string_view> splitFields(std::string_view line, std::string_view separators);

std::string_view trim(std::string_view s);

// Strict parsers: the whole field must be consumed and the value finite. `what` names the field in
// the error message ("column 3 (p_x)"). They throw through file.fail().
double parseDouble(std::string_view field, const TextFile& file, std::string_view what);
int64_t parseInt64(std::string_view field, const TextFile& file, std::string_view what);
// Seconds → integer nanoseconds. Plain decimals ("1403636580.83856") are converted exactly, digit
// by digit (a double holds an epoch time only to ~0.2 µs); exponent forms ("1.037359e-01", KITTI)
// go through double and are rounded to the nearest ns.
int64_t parseSecondsToNs(std::string_view field, const TextFile& file, std::string_view what);

// The same parsers without a file, for values that are not read line by line (YAML entries).
bool tryParseDouble(std::string_view field, double& value);

// `path` if it exists as a regular file, else `path + ".gz"` if that exists, else "".
std::string findPlainOrGz(const std::string& path);

}  // namespace marglab
