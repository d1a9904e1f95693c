#pragma once
// What a test sees of this process's memory: its peak resident size (a read that must not
// allocate here), and whether it is built with AddressSanitizer (MARGLAB_UNDER_ASAN), whose reports
// end a process where the release build goes on (an out-of-memory report, not std::bad_alloc).

#include <sys/resource.h>

#if defined(__SANITIZE_ADDRESS__)  // GCC; clang 14 answers only __has_feature
#define MARGLAB_UNDER_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define MARGLAB_UNDER_ASAN 1
#endif
#endif

namespace marglab::test {

// The peak resident set size of this process so far, in KiB.
inline long maxRssKb() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss;
}

}  // namespace marglab::test
