#include "core/data/text_file.h"

#include <fmt/core.h>

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>

#include "core/common/error.h"
#include "core/common/text_limits.h"

namespace marglab {

namespace fs = std::filesystem;

TextFile::TextFile(std::string path) : path_(std::move(path)) {
  std::error_code ec;
  if (!fs::exists(path_, ec)) throw InputError(path_, 0, "expected an existing file (not found)");
  if (!fs::is_regular_file(path_, ec)) throw InputError(path_, 0, "expected a regular file");
  file_ = gzopen(path_.c_str(), "rb");
  if (file_ == nullptr) {
    throw InputError(
        path_, 0, fmt::format("expected a readable file (cannot open: {})", std::strerror(errno)));
  }
  gzbuffer(file_, 1 << 17);
}

TextFile::~TextFile() {
  if (file_ != nullptr) gzclose(file_);
}

bool TextFile::nextLine(std::string_view& line) {
  buffer_.clear();
  char chunk[4096];
  bool got_any = false;
  while (gzgets(file_, chunk, sizeof(chunk)) != nullptr) {
    got_any = true;
    buffer_ += chunk;
    if (!buffer_.empty() && buffer_.back() == '\n') break;
    if (buffer_.size() > kMaxTextLineBytes) {
      ++line_;
      fail("expected a text file with lines of at most 1 MiB (a longer line, or binary data)");
    }
  }
  if (!got_any) {
    int err = Z_OK;
    const char* message = gzerror(file_, &err);
    if (err != Z_OK && err != Z_STREAM_END) {
      ++line_;
      fail(fmt::format("expected a readable text or gzip stream ({})", message));
    }
    return false;
  }
  ++line_;
  while (!buffer_.empty() && (buffer_.back() == '\n' || buffer_.back() == '\r')) buffer_.pop_back();
  line = buffer_;
  return true;
}

bool TextFile::nextDataLine(std::string_view& line) {
  while (nextLine(line)) {
    line = trim(line);
    if (line.empty() || line.front() == '#') continue;
    return true;
  }
  return false;
}

void TextFile::fail(const std::string& expected) const { throw InputError(path_, line_, expected); }

std::string_view trim(std::string_view s) {
  const auto blank = [](char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; };
  while (!s.empty() && blank(s.front())) s.remove_prefix(1);
  while (!s.empty() && blank(s.back())) s.remove_suffix(1);
  return s;
}

std::vector<std::string_view> splitFields(std::string_view line, std::string_view separators) {
  std::vector<std::string_view> fields;
  const bool collapse = separators.find(',') == std::string_view::npos;
  std::size_t start = 0;
  while (true) {
    const std::size_t end = line.find_first_of(separators, start);
    const std::string_view field = trim(line.substr(start, end - start));
    if (!collapse || !field.empty()) fields.push_back(field);
    if (end == std::string_view::npos) break;
    start = end + 1;
  }
  if (!collapse && fields.size() == 1 && fields.front().empty()) fields.clear();
  return fields;
}

bool tryParseDouble(std::string_view field, double& value) {
  if (!field.empty() && field.front() == '+') field.remove_prefix(1);
  if (field.empty()) return false;
  const auto [end, ec] = std::from_chars(field.data(), field.data() + field.size(), value);
  return ec == std::errc() && end == field.data() + field.size();
}

double parseDouble(std::string_view field, const TextFile& file, std::string_view what) {
  double value = 0;
  if (!tryParseDouble(field, value)) {
    file.fail(fmt::format("expected a number in {}, found '{}'", what, shortToken(field)));
  }
  if (!std::isfinite(value)) {
    file.fail(fmt::format("expected a finite number in {}, found '{}'", what, shortToken(field)));
  }
  return value;
}

int64_t parseInt64(std::string_view field, const TextFile& file, std::string_view what) {
  int64_t value = 0;
  std::string_view digits = field;
  if (!digits.empty() && digits.front() == '+') digits.remove_prefix(1);
  const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), value);
  if (digits.empty() || ec != std::errc() || end != digits.data() + digits.size()) {
    file.fail(fmt::format("expected an integer in {}, found '{}'", what, shortToken(field)));
  }
  return value;
}

int64_t parseSecondsToNs(std::string_view field, const TextFile& file, std::string_view what) {
  const std::size_t dot = field.find('.');
  const std::string_view whole = field.substr(0, dot);
  const std::string_view frac =
      dot == std::string_view::npos ? std::string_view() : field.substr(dot + 1);
  const auto all_digits = [](std::string_view s) {
    for (char c : s) {
      if (c < '0' || c > '9') return false;
    }
    return true;
  };
  if (!whole.empty() && whole.size() <= 10 && all_digits(whole) && all_digits(frac)) {
    int64_t ns = 0;
    for (char c : whole) ns = ns * 10 + (c - '0');
    if (ns > std::numeric_limits<int64_t>::max() / 1000000000 - 1) {
      file.fail(fmt::format("expected a time in seconds below 9.2e9 in {}, found '{}'", what,
                            shortToken(field)));
    }
    int64_t frac_ns = 0;
    for (std::size_t i = 0; i < 9; ++i)
      frac_ns = frac_ns * 10 + (i < frac.size() ? frac[i] - '0' : 0);
    // Digits beyond ns resolution round half up.
    if (frac.size() > 9 && frac[9] >= '5') ++frac_ns;
    return ns * 1000000000 + frac_ns;
  }
  const double seconds = parseDouble(field, file, what);
  if (std::abs(seconds) > 9.2e9) {
    file.fail(fmt::format("expected a time in seconds within ±9.2e9 in {}, found '{}'", what,
                          shortToken(field)));
  }
  return std::llround(seconds * 1e9);
}

std::string findPlainOrGz(const std::string& path) {
  for (const std::string& candidate : {path, path + ".gz"}) {
    std::error_code ec;
    const fs::file_status status = fs::status(candidate, ec);
    if (status.type() == fs::file_type::not_found) continue;
    if (ec) throw InputError(candidate, 0, "cannot read: " + ec.message());
    if (fs::is_regular_file(status)) return candidate;
    // A folder named like a data file must not read as "the file is absent".
    throw InputError(candidate, 0, "expected a regular file, found a folder or special file");
  }
  return "";
}

}  // namespace marglab
