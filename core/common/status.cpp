#include "core/common/status.h"

namespace marglab {

const char* toString(Status::Code code) {
  switch (code) {
    case Status::Code::kOk:
      return "ok";
    case Status::Code::kNotFinite:
      return "not_finite";
    case Status::Code::kSolveFailed:
      return "solve_failed";
    case Status::Code::kRankDeficient:
      return "rank_deficient";
    case Status::Code::kInvalidArgument:
      return "invalid_argument";
  }
  return "unknown";
}

std::string Status::toString() const {
  if (ok()) return "ok";
  return std::string(marglab::toString(code_)) + ": " + message_;
}

}  // namespace marglab
