#!/usr/bin/env bash
# Fails if any C++/CUDA source differs from `clang-format --style=file` (Google style).
set -euo pipefail
cd "$(dirname "$0")/.."
cf=$(command -v clang-format || command -v clang-format-14 || true)
if [ -z "$cf" ]; then echo "check_format: clang-format not installed" >&2; exit 1; fi
mapfile -t files < <(git ls-files -co --exclude-standard -- '*.h' '*.cc' '*.cu' '*.cuh' 2>/dev/null || find plugin gaussian watermark distortion tests -name '*.h' -o -name '*.cc')
existing=()
for f in "${files[@]}"; do [ -f "$f" ] && existing+=("$f"); done
# One clang-format process for every file (one per file cost 25 s of CPU on 2 cores, mostly process
# start-up); --dry-run -Werror names each file that differs, as file:line:col: error: ...
set +e
out=$("$cf" --style=file --dry-run -Werror "${existing[@]}" 2>&1)
rc=$?
set -e
bad=$(grep -oE '^[^:]+:[0-9]+:[0-9]+: error' <<< "$out" | cut -d: -f1 | sort -u || true)
if [ -n "$bad" ]; then
  while read -r f; do
    echo "check_format: $f is not clang-formatted (run: clang-format -i $f)" >&2
  done <<< "$bad"
  exit 1
fi
if [ $rc -ne 0 ]; then
  echo "check_format: clang-format failed: $(head -1 <<< "$out")" >&2
  exit 1
fi
echo "check_format: ${#existing[@]} files clean"
