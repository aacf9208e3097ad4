#!/usr/bin/env bash
# Issue 54 with the session-31 default (embed --target_psnr 38): the demo's default file
# (scripts/run_demo.sh's wm.ply) and the same raw model embedded with the default plus
# --jpeg_layer 90:0.5, each photographed by both web viewers at the 6 held-out cameras, JPEG 90,
# read by detect (measure.sh); the JPEG-layer file also read on watergs' own renders.
#   B=BINARY RAW=.../train/point_cloud.ply WM=.../wm.ply O=OUT bash run.sh
set -u
cd "$(dirname "$0")/../../.."
B=${B:?binary} RAW=${RAW:?raw model} WM=${WM:?default file} O=${O:?output folder}
S=datasets_scripts/demo_scene
mkdir -p "$O/jpeg_layer"
WATERGS_BIN=$B PATH=/usr/bin:$PATH bash results/viewers/reference_conventions/measure.sh "$RAW" "$WM" "$O/default" \
  > "$O/default.log" 2>&1
J=$O/jpeg_layer
[ -f "$J/wm.ply" ] || $B embed --input_path "$RAW" --workspace_path $S --downscale 2 --message text:WGS-26 \
  --output_path "$J/wm.ply" --iterations 1500 --split train --jpeg_layer 90:0.5 > "$J/embed.log" 2>&1
echo "embed rc $?" >> "$J/embed.log"
for q in 90 75; do
  $B extract --input_path "$J/wm.ply" --raw_path "$RAW" --workspace_path $S --downscale 2 --message text:WGS-26 \
    --split test --image_attack jpeg:$q --json "$J/extract_jpeg$q.json" > "$J/extract_jpeg$q.txt" 2>&1
done
$B extract --input_path "$J/wm.ply" --raw_path "$RAW" --workspace_path $S --downscale 2 --message text:WGS-26 \
  --split test --json "$J/extract_held.json" > "$J/extract_held.txt" 2>&1
$B extract --input_path "$J/wm.ply" --workspace_path $S --downscale 2 --message text:WGS-26 --split test \
  --json "$J/extract_held_blind.json" > "$J/extract_held_blind.txt" 2>&1
$B extract --input_path "$J/wm.ply" --workspace_path $S --downscale 2 --message text:WGS-26 \
  --json "$J/extract_all_blind.json" > "$J/extract_all_blind.txt" 2>&1
$B eval --raw_path "$RAW" --input_path "$J/wm.ply" --workspace_path $S --downscale 2 --message text:WGS-26 \
  --split test --attacks '' --image_attacks '' --lpips_weights '' --output_path "$J/eval" > "$J/eval.txt" 2>&1
WATERGS_BIN=$B PATH=/usr/bin:$PATH bash results/viewers/reference_conventions/measure.sh "$RAW" "$J/wm.ply" "$J/viewers" \
  > "$J/viewers.log" 2>&1
echo "all done" >> "$O/default.log"
