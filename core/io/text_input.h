#pragma once
// Bounded reads of the text files a user hands marglab (config, run spec, sweep file, text track
// file): `run --config /dev/zero` used to read until the host ran out of memory. The whole file
// is read into memory only up to `max_bytes`, no line may be longer than `max_line`, and a NUL
// byte (a binary file) is refused before any parser echoes raw bytes back; each failure is an
// InputError naming the file (and the line) and what was expected. Device nodes and FIFOs are
// read like files, within the same bounds. The line-by-line dataset reader (core/data/
// text_file.h) bounds its lines the same way.

#include <cstddef>
#include <string>

namespace marglab {

struct TextLimits {
  std::size_t max_bytes;
  std::size_t max_line;
};

// A config, a run spec, a sweep file: a few kB in practice.
inline constexpr TextLimits kSettingsTextLimits{16u << 20, 1u << 20};
// A text track file: tens of MB for a whole KITTI sequence.
inline constexpr TextLimits kTrackTextLimits{1024u << 20, 1u << 20};

// The file's text; `what` names it in the errors ("the config file"). Throws InputError.
std::string readTextInput(const std::string& path, const char* what, TextLimits limits);

}  // namespace marglab
