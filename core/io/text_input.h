#pragma once
// Bounded reads of the text files a user hands marglab (config, run spec, sweep file, text track
// file): `run --config /dev/zero` used to read until the host ran out of memory. The whole file
// is read into memory only up to `max_bytes`, no line may be longer than `max_line`, and a NUL
// byte (a binary file) is refused before any parser echoes raw bytes back; each failure is an
// InputError naming the file (and the line) and what was expected. Device nodes and FIFOs are
// read like files, within the same bounds. The line-by-line dataset reader (core/data/
// text_file.h) bounds its lines the same way.

#include <string>

#include "core/common/text_limits.h"

namespace marglab {

// The file's text; `what` names it in the errors ("the config file"). Throws InputError.
std::string readTextInput(const std::string& path, const char* what, TextLimits limits);

}  // namespace marglab
