#!/usr/bin/env bash
# Builds sdot with AddressSanitizer and UndefinedBehaviorSanitizer and runs the ctest suite on it.
#   scripts/test-sanitized.sh [BUILD_DIR]        (default: build-sanitized)
# SDOT_SANITIZERS overrides the -fsanitize list (default address,undefined). Any sanitizer report
# stops the program, so it fails its test. Left out: the tests labelled `package` and `install`,
# which build and install separate, unsanitized copies (they check packaging, not memory, and
# run in the normal suite). -O1 keeps the stacks readable and the run within CI's time.
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir=${1:-build-sanitized}
sanitizers=${SDOT_SANITIZERS:-address,undefined}
jobs=$(nproc)
cmake -S . -B "$build_dir" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g" \
  -DSDOT_SANITIZE="$sanitizers"
cmake --build "$build_dir" -j "$jobs"
export ASAN_OPTIONS=${ASAN_OPTIONS:-abort_on_error=1:detect_leaks=1:strict_string_checks=1:detect_stack_use_after_return=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
cd "$build_dir"
ctest --output-on-failure -j "$jobs" --timeout 1800 -LE "^(package|install)$"
