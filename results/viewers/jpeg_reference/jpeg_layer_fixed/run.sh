#!/usr/bin/env bash
set -u
cd /work/main
B=/tmp/wgs33
RAW=/work/runs/demo/train/point_cloud.ply
O=/work/runs/jpeg_fix
$B embed --input_path $RAW --workspace_path datasets_scripts/demo_scene --downscale 2 --message text:WGS-26 \
  --output_path $O/wm.ply --iterations 1500 --split train --jpeg_layer 90:0.5 > $O/embed.log 2>&1
echo "embed rc $?" >> $O/embed.log
for q in 90 75; do
  $B extract --input_path $O/wm.ply --raw_path $RAW --workspace_path datasets_scripts/demo_scene --downscale 2 \
    --message text:WGS-26 --split test --image_attack jpeg:$q --json $O/extract_jpeg$q.json > $O/extract_jpeg$q.txt 2>&1
done
$B extract --input_path $O/wm.ply --raw_path $RAW --workspace_path datasets_scripts/demo_scene --downscale 2 \
  --message text:WGS-26 --split test --json $O/extract_held.json > $O/extract_held.txt 2>&1
$B extract --input_path $O/wm.ply --workspace_path datasets_scripts/demo_scene --downscale 2 \
  --message text:WGS-26 --json $O/extract_all_blind.json > $O/extract_all_blind.txt 2>&1
$B eval --raw_path $RAW --input_path $O/wm.ply --workspace_path datasets_scripts/demo_scene --downscale 2 \
  --message text:WGS-26 --split test --attacks '' --image_attacks '' --lpips_weights '' --output_path $O/eval > $O/eval.txt 2>&1
WATERGS_BIN=$B SHOTS_ONLY=1 PATH=/usr/bin:$PATH bash results/viewers/reference_conventions/measure.sh $RAW $O/wm.ply $O/viewers > $O/viewers.log 2>&1
$B detect --image_path "$O/viewers/jpeg_gs3d_wm,$O/viewers/jpeg_playcanvas_wm" --message text:WGS-26 --raw_path $RAW \
  --workspace_path datasets_scripts/demo_scene --downscale 2 --json $O/detect_auto.json > $O/detect_auto.txt 2>&1
echo "all done" >> $O/embed.log
