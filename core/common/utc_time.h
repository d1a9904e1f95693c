#pragma once
// The current UTC time as ISO 8601 (e.g. "2026-11-22T07:17:53Z"), for provenance records.

#include <string>

namespace marglab {

std::string utcNowIso8601();

}  // namespace marglab
