#!/usr/bin/env bash
# Builds sdot with AddressSanitizer and UndefinedBehaviorSanitizer and runs the ctest suite on it.
#   scripts/test-sanitized.sh [BUILD_DIR]        (default: build-sanitized)
# SDOT_SANITIZERS overrides the -fsanitize list (default address,undefined), SDOT_SANITIZE_EXCLUDE
# the checks left out of it (default null,alignment: in g++ they are one check on every reference
# and member access, 40 % of sphere.cpp's compile time, see docs/reliability.md; ASan still
# reports a null dereference, and the fuzz build, scripts/fuzz.sh, keeps both checks on the
# readers). Any sanitizer report stops the program, so it fails its test. Left out: the tests
# labelled `package` and `install`, which build and install separate, unsanitized copies (they
# check packaging, not memory, and run in the normal suite). -O1 with line tables only (-g1)
# keeps the stacks readable and the run within CI's time.
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir=${1:-build-sanitized}
sanitizers=${SDOT_SANITIZERS:-address,undefined}
excluded=${SDOT_SANITIZE_EXCLUDE-null,alignment}
jobs=$(nproc)
cmake -S . -B "$build_dir" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1" \
  -DSDOT_SANITIZE="$sanitizers" -DSDOT_SANITIZE_EXCLUDE="$excluded"
cmake --build "$build_dir" -j "$jobs"
export ASAN_OPTIONS=${ASAN_OPTIONS:-abort_on_error=1:detect_leaks=1:strict_string_checks=1:detect_stack_use_after_return=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
cd "$build_dir"
ctest --output-on-failure -j "$jobs" --timeout 1800 -LE "^(package|install)$"
