#!/usr/bin/env bash
# Runs every benchmark of docs/benchmarks.md and regenerates its tables and docs/images/scaling.png.
#   scripts/bench.sh [--quick] [--build DIR] [other options of scripts/bench.py]
# --quick: N up to 1e5 and meshes up to 15k vertices, tables printed only (a few minutes).
# --large: also 1e7 sites on every geometry (11 GB of memory).
# With --large the full run took 14.8 minutes on the 2-core machine of docs/benchmarks.md (time scripts/bench.sh --large);
# run it on an otherwise idle machine.
set -euo pipefail
cd "$(dirname "$0")/.."
exec /usr/bin/python3 scripts/bench.py "$@"
