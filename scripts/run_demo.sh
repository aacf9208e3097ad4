#!/usr/bin/env bash
# The README's main job on the embedded demo scene. Grows with the product:
# today it summarises the COLMAP model; later: train, embed, attack, extract.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
bin="${WATERGS_BIN:-$root/build/plugin/watergs}"
scene="$root/datasets_scripts/demo_scene"
out="${1:-$root/build/demo}"
mkdir -p "$out"
run() { echo "+ watergs $*"; "$bin" "$@"; }
run model_info --input_path "$scene/sparse/0"
