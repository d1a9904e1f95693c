#include "core/io/text_input.h"

#include <fcntl.h>
#include <unistd.h>

#include <fmt/core.h>

#include <cerrno>
#include <cstring>

#include "core/common/error.h"

namespace marglab {
namespace {

std::string sizeText(std::size_t bytes) {
  return bytes >= (1u << 20) ? fmt::format("{} MiB", bytes >> 20) : fmt::format("{} bytes", bytes);
}

// Checks the text as it arrives, so that /dev/zero or a binary file fails at its first chunk.
class TextChecker {
 public:
  TextChecker(const std::string& path, const char* what, TextLimits limits)
      : path_(path), what_(what), limits_(limits) {}

  void append(const char* data, std::size_t size, std::string* text) {
    if (text->size() + size > limits_.max_bytes) {
      throw InputError(path_, 0,
                       fmt::format("larger than {}: expected {} (a text file)",
                                   sizeText(limits_.max_bytes), what_));
    }
    for (std::size_t i = 0; i < size; ++i) {
      if (data[i] == '\0') {
        throw InputError(path_, line_,
                         fmt::format("expected {} as text, found binary data (a "
                                     "NUL byte)",
                                     what_));
      }
      line_bytes_ = data[i] == '\n' ? 0 : line_bytes_ + 1;
      if (data[i] == '\n') ++line_;
      if (line_bytes_ > limits_.max_line) {
        throw InputError(path_, line_,
                         fmt::format("line longer than {}: expected {} as text",
                                     sizeText(limits_.max_line), what_));
      }
    }
    text->append(data, size);
  }

 private:
  const std::string& path_;
  const char* what_;
  TextLimits limits_;
  int line_ = 1;
  std::size_t line_bytes_ = 0;
};

// Closes the descriptor on every way out.
struct Descriptor {
  int fd;
  ~Descriptor() {
    if (fd >= 0) ::close(fd);
  }
};

}  // namespace

std::string readTextInput(const std::string& path, const char* what, TextLimits limits) {
  const Descriptor in{::open(path.c_str(), O_RDONLY | O_CLOEXEC)};
  if (in.fd < 0) {
    throw InputError(path, 0, fmt::format("cannot open {}: {}", what, std::strerror(errno)));
  }
  TextChecker checker(path, what, limits);
  std::string text;
  char chunk[1 << 16];
  for (;;) {
    const ssize_t n = ::read(in.fd, chunk, sizeof(chunk));
    if (n == 0) return text;
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      throw InputError(path, 0, fmt::format("cannot read {}: {}", what, std::strerror(errno)));
    }
    checker.append(chunk, static_cast<std::size_t>(n), &text);
  }
}

}  // namespace marglab
