#!/usr/bin/env bash
# The verdict's false-positive rate on unmarked views (docs/verification.md): renders unmarked
# models from their cameras and from free viewpoints, decodes photo crops, and tests them all
# against the message as a fixed claim and under many keys (watergs null_calibration).
#   datasets_scripts/null_calibration.sh OUT [NAME=PLY:WORKSPACE ...]
# Default model: the demo's raw model (build/demo/train/point_cloud.ply, from scripts/run_demo.sh)
# on the demo scene. Environment: WATERGS_BIN, DECODER, DOWNSCALE (2), VIEWS (free viewpoints a
# model, 4000), PHOTOS (photo folders, comma-separated; e.g. make_photo_corpus.sh's train and
# heldout), CROPS (a folder, 2000), KEYS (100000), OTHER=PLY:WORKSPACE (a model watermarked with
# text:WGS-26 by someone else: read against text:OTHER1 in a run of its own), RAW (the owner's raw
# model: every read is the owner's reading, extract --raw_path RAW, and the tables go to
# OUT/owner.md and OUT/owner.json instead).
# Resumable: each model's reads are kept in OUT and not redone.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
out=${1:?usage: null_calibration.sh OUT [NAME=PLY:WORKSPACE ...]}; shift
bin="${WATERGS_BIN:-$root/build/plugin/watergs}"
decoder="${DECODER:-$root/watermark/models/decoder_48_residual_pool2.bin}"
ds="${DOWNSCALE:-2}"; views="${VIEWS:-4000}"; keys="${KEYS:-100000}"
models=("$@")
[ ${#models[@]} -gt 0 ] || models=("demo=$root/build/demo/train/point_cloud.ply:$root/datasets_scripts/demo_scene")
mkdir -p "$out"
owner=() reading=() table=unmarked
if [ -n "${RAW:-}" ]; then owner=(--raw_path "$RAW") reading=(--reading owner) table=owner; fi
read_views() {  # NAME PLY WORKSPACE JSON [extract options]
  local name=$1 ply=$2 ws=$3 json=$4; shift 4
  [ -f "$json" ] && return 0
  [ -f "$ply" ] || { echo "null_calibration.sh: $ply: no such model ($name)" >&2; exit 1; }
  echo "null_calibration.sh: reading $name ($*)"
  "$bin" extract --input_path "$ply" --workspace_path "$ws" --downscale "$ds" \
    --decoder "$decoder" --json "$json.tmp" "${owner[@]}" "$@" > "$out/$(basename "$json" .json).log" 2>&1
  mv "$json.tmp" "$json"
}
logits=()
seed=11
for entry in "${models[@]}"; do
  name=${entry%%=*}; rest=${entry#*=}; ply=${rest%%:*}; ws=${rest#*:}
  read_views "$name" "$ply" "$ws" "$out/${name}_cams.json"
  read_views "$name" "$ply" "$ws" "$out/${name}_free.json" --num_views "$views" --seed "$seed"
  logits+=("$out/${name}_cams.json" "$out/${name}_free.json")
  seed=$((seed + 1))
done
photos=()
[ -z "${PHOTOS:-}" ] || photos=(--image_path "$PHOTOS" --crop 128 --crops "${CROPS:-2000}")
common=(--decoder "$decoder" --keys "$keys" --single_keys 3 --aggregate 1,6,48 --aggregates 200)
"$bin" null_calibration "${common[@]}" "${reading[@]}" --logits "$(IFS=,; echo "${logits[*]}")" \
  "${photos[@]}" --markdown "$out/$table.md" --json "$out/$table.json" > "$out/$table.log"
echo "null_calibration.sh: wrote $out/$table.md"
if [ -n "${OTHER:-}" ]; then
  ply=${OTHER%%:*}; ws=${OTHER#*:}
  read_views other "$ply" "$ws" "$out/marked_by_another_free.json" --num_views 1000 --seed "$seed"
  "$bin" null_calibration "${common[@]}" --logits "$out/marked_by_another_free.json" \
    --message text:OTHER1 --markdown "$out/marked_by_another.md" \
    --json "$out/marked_by_another.json" > "$out/marked_by_another.log"
  echo "null_calibration.sh: wrote $out/marked_by_another.md"
fi
