#!/usr/bin/env bash
# Builds every target (library, command, examples, tests, Python module) with clang-14, warnings
# on, without running anything: code that only g++ accepts (clang 14 lacks some C++20 features,
# such as lambdas that capture structured bindings) fails here instead of in scripts/fuzz.sh.
# Unoptimized (-O0, asserts on): nothing runs, and sphere.cpp compiles in 5.8 s instead of 13.3 s at -O3.
#   scripts/build-clang.sh [BUILD_DIR]        (default: build-clang)
# Needs clang-14 and libomp-14-dev (scripts/install-deps.sh lists them); installs nothing itself.
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir=${1:-build-clang}
if ! command -v clang++-14 > /dev/null; then
  echo "build-clang: clang++-14 not found (Debian: apt-get install clang-14 libomp-14-dev)" >&2
  exit 2
fi
cmake -S . -B "$build_dir" -DCMAKE_CXX_COMPILER=clang++-14 -DCMAKE_BUILD_TYPE=Debug -DCMAKE_CXX_FLAGS_DEBUG="-O0" > /dev/null
cmake --build "$build_dir" -j "$(nproc)"
