#!/usr/bin/env bash
# Builds sdot in Release with the stress test and runs it: 1000 random clustered problems per
# geometry (tests/stress/stress_test.cpp), outside the default ctest run.
#   scripts/stress.sh [BUILD_DIR]        (default: build-stress)
# Each geometry is one ctest test running single-threaded (OMP_NUM_THREADS=1, set by the test's
# properties: at N ≤ 2000 threads gain little and lose much on a busy machine), so ctest runs them
# side by side on the machine's cores. Every problem's failure names its index k; rerun it alone
# with SDOT_STRESS_PROBLEM=k BUILD_DIR/bin/stress_test. The summaries (lines `stress[...]`) are
# printed at the end from ctest's log.
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir=${1:-build-stress}
jobs=$(nproc)
cmake -S . -B "$build_dir" -DCMAKE_BUILD_TYPE=Release -DSDOT_STRESS_TESTS=ON
cmake --build "$build_dir" -j "$jobs" --target stress_test
cd "$build_dir"
ctest -L stress --output-on-failure -j "$jobs"
grep -h '^stress\[' Testing/Temporary/LastTest.log
