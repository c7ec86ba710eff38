#!/usr/bin/env bash
# Builds the API reference with Doxygen and fails when it warns (e.g. an undocumented public name).
#   scripts/check-api-docs.sh [BUILD_DIR]    (default: build; a configured build directory)
# Exit 0: no warnings; 1: warnings (printed) or doxygen failed; 77: doxygen not found (skipped,
# the ctest test api_docs_warnings has SKIP_RETURN_CODE 77). $DOXYGEN overrides the executable.
set -euo pipefail
build_dir=${1:-build}
doxygen=${DOXYGEN:-doxygen}
if ! command -v "$doxygen" >/dev/null 2>&1; then
  echo "check-api-docs: doxygen not found, skipped (Debian: apt-get install doxygen)"
  exit 77
fi
docs_dir=$build_dir/docs
doxyfile=$docs_dir/Doxyfile
if [ ! -f "$doxyfile" ]; then
  echo "check-api-docs: $doxyfile missing: configure first (cmake -S . -B $build_dir)" >&2
  exit 1
fi
# The check means something only with these settings (and the log where this script reads it).
for setting in "WARN_IF_UNDOCUMENTED *= *YES" "WARN_IF_DOC_ERROR *= *YES" "EXTRACT_ALL *= *NO" \
               "WARN_LOGFILE *= *.*/doxygen-warnings.log"; do
  if ! grep -Eq "^$setting\$" "$doxyfile"; then
    echo "check-api-docs: $doxyfile does not set $setting" >&2
    exit 1
  fi
done
# A Doxyfile.in edited since the last configure is not in effect until cmake runs again.
template=$(cd "$(dirname "$0")/.." && pwd)/docs/Doxyfile.in
if [ "$template" -nt "$doxyfile" ]; then
  echo "check-api-docs: note: docs/Doxyfile.in is newer than $doxyfile; re-run cmake to apply it" >&2
fi
log=$docs_dir/doxygen-warnings.log
html=$docs_dir/api
rm -rf "$log" "$html"
version=$("$doxygen" --version)
if ! (cd "$docs_dir" && "$doxygen" Doxyfile); then
  echo "check-api-docs: doxygen $version failed" >&2
  [ -s "$log" ] && cat "$log" >&2
  exit 1
fi
# Doxygen ran and read the headers: the log exists and the reference has the main entry points.
for page in "$log" "$html/index.html" "$html/namespacesdot.html" "$html/structsdot_1_1Options.html"; do
  if [ ! -e "$page" ]; then
    echo "check-api-docs: doxygen $version did not write $page" >&2
    exit 1
  fi
done
if [ -s "$log" ]; then
  cat "$log"
  echo "check-api-docs: $(grep -cE 'warning:|error:' "$log") Doxygen $version warning(s) (log: $log)" >&2
  exit 1
fi
echo "check-api-docs: no warnings (doxygen $version), HTML in $html"
