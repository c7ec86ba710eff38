#!/usr/bin/env bash
# Packaging test: install sdot to a scratch prefix, then build and run a consumer with
# find_package(sdot), and another with add_subdirectory (at -O0: it compiles sdot's sources again,
# faster than in Release, and the consumer only solves a 200-site problem).
set -euo pipefail
source_dir=$1
build_dir=$2
scratch=$(mktemp -d)
trap 'rm -rf "$scratch"' EXIT
cmake --install "$build_dir" --prefix "$scratch/prefix" > /dev/null
cmake -S "$source_dir/examples/custom_problem" -B "$scratch/find_package" -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_PREFIX_PATH="$scratch/prefix" > /dev/null
cmake --build "$scratch/find_package" -j 2 > /dev/null
"$scratch/find_package/custom_problem" | tail -2
mkdir -p "$scratch/sub"
cat > "$scratch/sub/CMakeLists.txt" <<CMAKE
cmake_minimum_required(VERSION 3.24)
project(sub LANGUAGES CXX)
add_subdirectory("$source_dir" sdot)
add_executable(sub_consumer "$source_dir/examples/custom_problem/main.cpp")
target_link_libraries(sub_consumer PRIVATE sdot::sdot)
CMAKE
cmake -S "$scratch/sub" -B "$scratch/sub/build" -DCMAKE_BUILD_TYPE=Debug -DCMAKE_CXX_FLAGS_DEBUG=-O0 > /dev/null
cmake --build "$scratch/sub/build" -j 2 --target sub_consumer > /dev/null
"$scratch/sub/build/sub_consumer" | tail -1
echo "package consumers: OK"
