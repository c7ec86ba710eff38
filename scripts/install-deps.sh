#!/usr/bin/env bash
# Installs the Debian packages sdot needs, when missing (sudo only when not root).
set -euo pipefail
packages=(cmake g++ make libeigen3-dev libboost-dev libqhull-dev libcgal-dev libpng-dev libfmt-dev libgtest-dev libsuitesparse-dev
          libopenblas0-pthread
          nlohmann-json3-dev python3-numpy
          pybind11-dev python3-dev python3-pytest python3-matplotlib python3-setuptools python3-wheel python3-pip
          python3-venv python3-nibabel  # nibabel: the FreeSurfer cross-check (python/tests/test_freesurfer.py)
          python3-dask python3-distributed  # sdot.batch (python/sdot/batch.py, docs/scaling.md)
          doxygen
          clang-14 libfuzzer-14-dev libomp-14-dev)  # scripts/fuzz.sh (libFuzzer harnesses, tests/fuzz), scripts/build-clang.sh
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all packages present"
  exit 0
fi
echo "install-deps: installing ${missing[*]}"
sudo=""
if [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -qq
$sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
