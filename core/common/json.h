#pragma once
// JSON output through nlohmann::json (Debian nlohmann-json3-dev) instead of format strings:
// objects keep their keys in the order written (ordered_json), strings are escaped, NaN and
// infinities are written as null, and a double as the shortest text that reads back to it.

#include <nlohmann/json.hpp>

namespace marglab {

using Json = nlohmann::ordered_json;

// x rounded to `significant` decimal digits — the value "{:.<significant>g}" prints: what a report
// keeps of a measured time, whose further digits are noise. Non-finite x is returned as is.
double roundedTo(double x, int significant);

}  // namespace marglab
