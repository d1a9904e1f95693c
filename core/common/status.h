#pragma once
// Numerical failure is a value, not an exception: kernels return a Status (code + message) that
// the estimator records per frame. Exceptions are reserved for bad input (see error.h).

#include <string>
#include <utility>

namespace marglab {

class Status {
 public:
  enum class Code { kOk, kNotFinite, kSolveFailed, kRankDeficient, kInvalidArgument };

  Status() = default;
  static Status Ok() { return Status(); }
  static Status Error(Code code, std::string message) { return Status(code, std::move(message)); }

  bool ok() const { return code_ == Code::kOk; }
  Code code() const { return code_; }
  const std::string& message() const { return message_; }
  std::string toString() const;

 private:
  Status(Code code, std::string message) : code_(code), message_(std::move(message)) {}
  Code code_ = Code::kOk;
  std::string message_;
};

const char* toString(Status::Code code);

}  // namespace marglab
