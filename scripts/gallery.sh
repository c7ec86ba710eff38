#!/usr/bin/env bash
# Regenerates the pictures of docs/gallery.md into docs/images/gallery/ (scripts/gallery.py).
# Needs a build: the Python package in BUILD/python, BUILD/bin/sdot-sphere-param and
# BUILD/bin/cross_geometry_test (scripts/build.sh makes them), and matplotlib.
#   scripts/gallery.sh [--build DIR] [NAME ...]   DIR: default build; NAME: image, holes, sphere,
#       hyperbolic, parameterization, convergence (default all); other options go to gallery.py
#       (--mesh FILE | --mesh generated, --out DIR). Relative paths are from the repository root.
set -euo pipefail
cd "$(dirname "$0")/.."

build=build
args=()
while (($#)); do
  case "$1" in
    --build) build=${2:?--build needs a directory}; shift 2 ;;
    --build=*) build=${1#--build=}; shift ;;
    -h|--help) sed -n '2,7p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) args+=("$1"); shift ;;
  esac
done

for needed in "$build/python/sdot/__init__.py" "$build/bin/sdot-sphere-param" "$build/bin/cross_geometry_test"; do
  if [[ ! -e $needed ]]; then
    echo "gallery.sh: $needed is missing: build first (scripts/build.sh)" >&2
    exit 2
  fi
done

python=${PYTHON:-/usr/bin/python3}
start=$SECONDS
PYTHONPATH="$build/python${PYTHONPATH:+:$PYTHONPATH}" MPLBACKEND=Agg \
  "$python" scripts/gallery.py --build "$build" ${args[@]+"${args[@]}"}
echo "gallery.sh: done in $((SECONDS - start)) s"
