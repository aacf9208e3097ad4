#!/usr/bin/env bash
# Fails if any C++/CUDA source differs from `clang-format --style=file` (Google style).
set -euo pipefail
cd "$(dirname "$0")/.."
cf=$(command -v clang-format || command -v clang-format-14 || true)
if [ -z "$cf" ]; then echo "check_format: clang-format not installed" >&2; exit 1; fi
mapfile -t files < <(git ls-files -co --exclude-standard -- '*.h' '*.cc' '*.cu' '*.cuh' 2>/dev/null || find plugin gaussian watermark distortion tests -name '*.h' -o -name '*.cc')
bad=0
for f in "${files[@]}"; do
  [ -f "$f" ] || continue
  if ! diff -q <("$cf" --style=file "$f") "$f" >/dev/null; then
    echo "check_format: $f is not clang-formatted (run: clang-format -i $f)" >&2
    bad=1
  fi
done
[ $bad -eq 0 ] && echo "check_format: ${#files[@]} files clean"
exit $bad
