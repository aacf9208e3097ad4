#!/usr/bin/env bash
# Issue 52's decoder designs for the blind reader: builds each design's decoder from the photo
# corpus (datasets_scripts/make_photo_corpus.sh; wallpapers and OpenCV samples, no scene it is
# judged on), measures its lean on the unmarked demo model's 48 renders and its false positives
# on held-out photo crops, reads the raw model blind (48 views together: must be "absent"), then
# embeds the demo blind at each fidelity point with single_view_probe.sh. One design a call, so
# a stopped run resumes where it stopped (each finished step leaves its file).
#   datasets_scripts/blind_decoder_designs.sh OUT CORPUS DESIGN
# POINTS (environment, default "inria lr02_mse50") chooses the points; POINTS= builds and measures
# the decoder only.
# DESIGN: shipped | steerable256 | residual2 | pool2 | pool1 | residual2_pool2 | residual2_pool2_blur2 |
#   residual2_pool2_scenes | residual2_steerable256 (blur2: calibrated on photo crops blurred by
#   sigma uniform in [0, 2] px; scenes: on the corpus's photos and every third image of
#   SCENE_RENDERS, renders of training scenes that are never judged with this decoder)
# Writes OUT/DESIGN/{decoder.bin,make_decoder.json,lean.json,raw_blind.json} and appends the
# embedding points to OUT/results.txt (labels DESIGN_POINT).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
out=${1:?usage: blind_decoder_designs.sh OUT CORPUS DESIGN}; corpus=${2:?corpus}; design=${3:?design}
bin="${WATERGS_BIN:-$root/build/plugin/watergs}"
scene="$root/datasets_scripts/demo_scene"
dir="$out/$design"; mkdir -p "$dir"
case "$design" in
  shipped) options=() ;;
  steerable256) options=(--steerable_subspace 256) ;;
  residual2) options=(--highpass 2) ;;
  pool2) options=(--pool 2) ;;
  pool1) options=(--pool 1) ;;
  residual2_pool2) options=(--highpass 2 --pool 2) ;;
  residual2_pool2_blur2) options=(--highpass 2 --pool 2 --calibration_blur 2) ;;
  residual2_pool2_scenes) options=(--highpass 2 --pool 2) ;;
  residual2_steerable256) options=(--highpass 2 --steerable_subspace 256) ;;
  *) echo "blind_decoder_designs: unknown design '$design'" >&2; exit 2 ;;
esac
decoder="$dir/decoder.bin"
if [ "$design" = shipped ]; then
  decoder="$root/watermark/models/decoder_48.bin"
elif [ ! -f "$decoder" ]; then
  calibration="$corpus/train"
  if [ "$design" = residual2_pool2_scenes ]; then
    renders=${SCENE_RENDERS:?residual2_pool2_scenes needs SCENE_RENDERS (renders of training scenes)}
    calibration="$dir/calibration"; rm -rf "$calibration"; mkdir -p "$calibration"
    for f in "$corpus"/train/*; do ln -s "$(readlink -f "$f")" "$calibration/photo_$(basename "$f")"; done
    find "$renders" -maxdepth 1 -name '*.png' | sort | awk 'NR % 3 == 1' | while read -r f; do
      ln -s "$(readlink -f "$f")" "$calibration/render_$(basename "$f")"; done
  fi
  "$bin" make_decoder --image_path "$calibration" --validation_path "$corpus/heldout" \
    --output_path "$dir/tmp.bin" --json "$dir/make_decoder.json" "${options[@]}" > "$dir/make_decoder.log"
  mv "$dir/tmp.bin" "$decoder"
fi
# The raw model (trained once, as single_view_probe.sh trains it) and its 48 renders.
raw="$out/raw/point_cloud.ply"
if [ ! -f "$raw" ]; then
  mkdir -p "$out/raw"
  "$bin" train --workspace_path "$scene" --output_path "$out/raw" --downscale 2 \
    --iterations 2000 --densify_until_iter 1000 --split train --test_iterations 2000 > "$out/raw.log"
fi
if [ ! -d "$out/raw_renders" ]; then
  "$bin" render --input_path "$raw" --workspace_path "$scene" --downscale 2 --split all \
    --output_path "$out/raw_renders.tmp" > "$out/raw_renders.log"
  mv "$out/raw_renders.tmp" "$out/raw_renders"
fi
[ -f "$dir/lean.json" ] || "$bin" decoder_stats --decoder "$decoder" --image_path "$out/raw_renders" \
  --message text:WGS-26 --json "$dir/lean.json" > "$dir/lean.txt"
[ -f "$dir/raw_blind.json" ] || "$bin" extract --input_path "$raw" --workspace_path "$scene" \
  --downscale 2 --decoder "$decoder" --message text:WGS-26 --json "$dir/raw_blind.json" > "$dir/raw_blind.txt"
# Two fidelity points: the blind defaults (margin 3, Inria's rates, L1 + D-SSIM to the photos),
# and margin 3 at the owner default's rates and MSE towards the input's renders.
probe() {  # POINT [embed options]
  local label="${design}_$1"; shift
  grep -q "^$label " "$out/results.txt" 2>/dev/null && return 0
  RAW="$raw" DECODER="$decoder" bash "$root/datasets_scripts/single_view_probe.sh" "$out" "$label" \
    --reading blind "$@"
}
for point in ${POINTS-inria lr02_mse50}; do
  case "$point" in
    inria) probe inria ;;
    lr02_mse50) probe lr02_mse50 --lr_scale 0.2 --fidelity input --mse_weight 50 ;;
    *) echo "blind_decoder_designs: unknown point '$point'" >&2; exit 2 ;;
  esac
done
