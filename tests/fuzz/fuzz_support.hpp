#pragma once
// Shared by the libFuzzer harnesses: how a harness reports a bug that is not a crash.

#include <cstdio>
#include <cstdlib>

namespace sdot::fuzz {

/// A broken promise of a reader (a NaN, an index out of range): reported like a crash, so that
/// libFuzzer keeps the input.
[[noreturn]] inline void fail(const char* what) {
  std::fprintf(stderr, "fuzz harness: %s\n", what);
  std::abort();
}

}  // namespace sdot::fuzz
