#pragma once
// How much of a text file a user hands in marglab reads (core/io/text_input.h reads whole files,
// core/data/text_file.h line by line): bounded, so that `--config /dev/zero` is an input error
// and never a process that reads until the host runs out of memory.

#include <cstddef>

namespace marglab {

// No text line of any input is longer: a longer one is binary data or a broken file.
inline constexpr std::size_t kMaxTextLineBytes = 1u << 20;

struct TextLimits {
  std::size_t max_bytes;
  std::size_t max_line;
};

// A config, a run spec, a sweep file: a few kB in practice.
inline constexpr TextLimits kSettingsTextLimits{16u << 20, kMaxTextLineBytes};
// A text track file: tens of MB for a whole KITTI sequence.
inline constexpr TextLimits kTrackTextLimits{1024u << 20, kMaxTextLineBytes};

}  // namespace marglab
