#!/usr/bin/env bash
# Builds the libFuzzer harnesses of the readers (tests/fuzz) with clang-14 and runs each one.
#   scripts/fuzz.sh [SECONDS]          each harness for SECONDS (default 30, as in CI)
# Build folder: build-fuzz, or $SDOT_FUZZ_BUILD_DIR. Needs clang-14, libfuzzer-14-dev and
# libomp-14-dev (scripts/install-deps.sh lists them); installs nothing itself.
# The seeds (scripts/fuzz_corpus.py) go to BUILD/fuzz/corpus/HARNESS, which keeps what the runs
# add; logs go to BUILD/fuzz/logs. A finding (crash, sanitizer report, uncaught exception,
# leak, timeout of 10 s, more than 2048 MB) is written to BUILD/fuzz/findings/HARNESS-crash-…
# (leak-, timeout-, oom-) and the script exits 1 after the other harnesses. Reproduce with
#   BUILD/bin/fuzz_HARNESS FILE                          (runs that one input, prints the report)
#   BUILD/bin/fuzz_HARNESS -minimize_crash=1 -runs=100000 FILE   (a smaller input with the same crash)
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-30}
build=${SDOT_FUZZ_BUILD_DIR:-build-fuzz}
harnesses=(off obj ply freesurfer pgm png problem mesh_density)
declare -A dictionary=([off]=off [obj]=obj [ply]=ply [pgm]=pgm [png]=png [problem]=json [mesh_density]=json)
if ! command -v clang++-14 > /dev/null; then
  echo "fuzz: clang++-14 not found (Debian: apt-get install clang-14 libfuzzer-14-dev libomp-14-dev)" >&2
  exit 2
fi

# -O2: Eigen's fixed-size code needs inlining, or the coverage hooks dominate the solver harnesses.
# Line tables only: the reports' stacks have files and lines, and the build is faster than with -g.
cmake -S . -B "$build" -DCMAKE_CXX_COMPILER=clang++-14 -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -gline-tables-only" -DSDOT_FUZZ=ON -DSDOT_BUILD_TESTS=OFF -DSDOT_BUILD_EXAMPLES=OFF \
  -DSDOT_BUILD_PYTHON=OFF > /dev/null
cmake --build "$build" -j "$(nproc)" --target "${harnesses[@]/#/fuzz_}"
/usr/bin/python3 scripts/fuzz_corpus.py "$build/fuzz/corpus" > /dev/null
mkdir -p "$build/fuzz/findings" "$build/fuzz/logs"

export OMP_NUM_THREADS=1  # one core per harness; the solver's parallel loops add nothing here
status=0
printf "%-13s %8s %12s %10s %8s  %s\n" harness seconds executions "exec/s" corpus result
for harness in "${harnesses[@]}"; do
  options=(-max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -print_final_stats=1
           -artifact_prefix="$build/fuzz/findings/$harness-")
  if [ -n "${dictionary[$harness]:-}" ]; then options+=(-dict="tests/fuzz/${dictionary[$harness]}.dict"); fi
  log="$build/fuzz/logs/$harness.log"
  result=ok
  start=$SECONDS
  "$build/bin/fuzz_$harness" "${options[@]}" "$build/fuzz/corpus/$harness" > "$log" 2>&1 || result=FINDING
  stat() { grep -o "stat::$1: *[0-9]*" "$log" | grep -o '[0-9]*$' || echo "?"; }
  printf "%-13s %8s %12s %10s %8s  %s\n" "$harness" "$((SECONDS - start))" "$(stat number_of_executed_units)" \
    "$(stat average_exec_per_sec)" "$(find "$build/fuzz/corpus/$harness" -type f | wc -l)" "$result"
  if [ "$result" != ok ]; then
    status=1
    grep -E "^(==[0-9]+==ERROR|SUMMARY|fuzz harness:|.*runtime error:|artifact_prefix=|Test unit written)" "$log" |
      sed 's/^/    /' || true
    echo "    log: $log"
  fi
done
exit $status
