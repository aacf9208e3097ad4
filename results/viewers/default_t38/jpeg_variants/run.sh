#!/usr/bin/env bash
# Session 31: JPEG-layer variants beside the default (t38) on the demo: fraction 1 at Q90, fraction 0.5 at Q80.
cd /work/main
B=/tmp/wgsS31/watergs RAW=/work/runs/demo31/train/point_cloud.ply S=datasets_scripts/demo_scene
for v in 90:1 80:0.5; do
  J=/work/runs/jpegvar31/${v/:/_}; mkdir -p $J
  [ -f $J/wm.ply ] || nice $B embed --input_path $RAW --workspace_path $S --downscale 2 --message text:WGS-26 \
    --output_path $J/wm.ply --iterations 1500 --split train --jpeg_layer $v > $J/embed.log 2>&1
  for q in 90; do
    nice $B extract --input_path $J/wm.ply --raw_path $RAW --workspace_path $S --downscale 2 --message text:WGS-26 \
      --split test --image_attack jpeg:$q --json $J/extract_jpeg$q.json > $J/extract_jpeg$q.txt 2>&1
  done
  nice $B extract --input_path $J/wm.ply --raw_path $RAW --workspace_path $S --downscale 2 --message text:WGS-26 \
    --split test --json $J/extract_held.json > $J/extract_held.txt 2>&1
  nice $B eval --raw_path $RAW --input_path $J/wm.ply --workspace_path $S --downscale 2 --message text:WGS-26 \
    --split test --attacks '' --image_attacks '' --lpips_weights '' --output_path $J/eval > $J/eval.txt 2>&1
  WATERGS_BIN=$B PATH=/usr/bin:$PATH nice bash results/viewers/reference_conventions/measure.sh $RAW $J/wm.ply $J/viewers > $J/viewers.log 2>&1
done
echo done > /work/runs/jpegvar31/done
