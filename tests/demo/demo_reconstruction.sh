#!/usr/bin/env bash
# CTest fixture (demo_reconstruction): `watergs reconstruct` on the demo scene's 48 photos, once
# per test run, into OUT/ws with its output in OUT/run1.log and OUT/run1.err. reconstruct_test
# checks it and pipeline_test starts from a copy of it, so COLMAP runs once for both.
#   tests/demo/demo_reconstruction.sh OUT
set -euo pipefail
bin="${WATERGS_BIN:?WATERGS_BIN: the watergs CLI}"
root="$(cd "$(dirname "$0")/../.." && pwd)"
out=${1:?usage: demo_reconstruction.sh OUT}
command -v colmap > /dev/null || { echo "demo_reconstruction: colmap not installed (scripts/install_deps.sh --tests)"; exit 77; }
rm -rf "$out"
mkdir -p "$out"
# The defaults (2,048 features, every pair): 1,024 features placed a third of the photos half a
# turn wrong on the scene's repeating floor (docs/reconstruct.md).
if ! "$bin" reconstruct --image_path "$root/datasets_scripts/demo_scene/images" --workspace_path "$out/ws" \
    > "$out/run1.log" 2> "$out/run1.err"; then
  echo "demo_reconstruction: FAIL: reconstruct: $(tail -3 "$out/run1.log" "$out/run1.err")" >&2
  rm -rf "$out/ws"
  exit 1
fi
tail -1 "$out/run1.log"
