#!/usr/bin/env bash
# Checks that `pip install --no-build-isolation .` works offline with Debian's packages only: copies
# the tracked files to a temporary folder, installs them into a fresh virtual environment that sees
# Debian's numpy (--system-site-packages), imports sdot from there and solves on every geometry.
# The module is built unoptimized (SDOT_CMAKE_ARGS, default -O0; set it empty for setup.py's
# Release build): the test checks the install path, not speed, and -O0 compiles faster.
set -euo pipefail
export SDOT_CMAKE_ARGS=${SDOT_CMAKE_ARGS--DCMAKE_BUILD_TYPE=Debug -DCMAKE_CXX_FLAGS_DEBUG=-O0}
cd "$(dirname "$0")/.."
python=${SDOT_PYTHON:-/usr/bin/python3}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
git ls-files -z --cached --others --exclude-standard | xargs -0 cp --parents -t "$work" 2>/dev/null || { echo "test-pip-install: needs a git checkout"; exit 1; }
"$python" -m venv --system-site-packages "$work/venv"
(cd "$work" && "$work/venv/bin/pip" install --no-build-isolation --no-index --quiet .)
cd "$work/venv"  # not the source tree: import the installed package
"$work/venv/bin/python" - <<'PY'
import numpy as np, sdot
assert sdot.__file__.startswith(__import__("sys").prefix), sdot.__file__
rng = np.random.default_rng(0)
plane = sdot.solve(rng.random((300, 2)))
x = rng.normal(size=(300, 3))
sphere = sdot.solve(x / np.linalg.norm(x, axis=1, keepdims=True), geometry="sphere")
hexagon = 0.8 * np.column_stack((np.cos(np.arange(6) * np.pi / 3), np.sin(np.arange(6) * np.pi / 3)))
h2 = sdot.solve(rng.uniform(-0.4, 0.4, (100, 2)), geometry="hyperbolic", domain=hexagon)
assert plane.converged and sphere.converged and h2.converged
print("installed sdot", sdot.__version__, "from", sdot.__file__, ": 3 geometries converged")
PY
