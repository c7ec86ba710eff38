#!/usr/bin/env bash
# README command (1): install what is missing, build in Release, run the demo into out/.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
scripts/build.sh
build/bin/sdot demo --out out
echo "demo: results and pictures are in $(pwd)/out"
