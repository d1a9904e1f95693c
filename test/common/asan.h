#pragma once
// MARGLAB_UNDER_ASAN: defined when the test is built with AddressSanitizer, whose reports end a
// process where the release build goes on (an out-of-memory report instead of std::bad_alloc).

#if defined(__SANITIZE_ADDRESS__)  // GCC; clang 14 answers only __has_feature
#define MARGLAB_UNDER_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define MARGLAB_UNDER_ASAN 1
#endif
#endif
