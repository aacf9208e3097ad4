#!/usr/bin/env bash
# The "HiDDeN + 3DGS" baseline of the paper (Sec. 5): watermark a workspace's training images
# with a HiDDeN encoder, train 3DGS on them, and try to read the message from the renders. The
# paper's finding to check: the message does not survive 3DGS training (BER near 50%).
set -euo pipefail

usage() {
  cat <<'USAGE'
Usage: datasets_scripts/baseline_hidden_3dgs.sh --model WEIGHTS --out DIR [options]

Writes, under DIR:
  images/          the workspace's images watermarked by the encoder (encode_images)
  encode.txt       their PSNR against the covers and the BER read back from them
  model/           the 3DGS model trained on them (train --image_path DIR/images --split train)
  extract.json     the BER and verdict read from renders of the trained model (extract)
  commands.txt     the exact commands run

Options:
  --model FILE        HiDDeN weights with an encoder (train_decoder's output)
  --out DIR           output folder
  --workspace DIR     COLMAP workspace (default datasets_scripts/demo_scene)
  --binary PATH       watergs executable (default build/plugin/watergs)
  --message TEXT      message (default text:WGS-26)
  --iterations N      3DGS training iterations (default 30000)
  --downscale D       image downscale for training and extraction (default 1)
USAGE
}

model="" out="" workspace=datasets_scripts/demo_scene binary=build/plugin/watergs
message=text:WGS-26 iterations=30000 downscale=1
while [[ $# -gt 0 ]]; do
  case "$1" in
    --model) model="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    --workspace) workspace="$2"; shift 2 ;;
    --binary) binary="$2"; shift 2 ;;
    --message) message="$2"; shift 2 ;;
    --iterations) iterations="$2"; shift 2 ;;
    --downscale) downscale="$2"; shift 2 ;;
    -h|--help) usage; exit 0 ;;
    *) echo "baseline_hidden_3dgs.sh: unknown option $1" >&2; usage >&2; exit 2 ;;
  esac
done
[[ -n "$model" && -n "$out" ]] || { usage >&2; exit 2; }
mkdir -p "$out"

source "$(dirname "${BASH_SOURCE[0]}")/lib_baseline.sh"
run() { baseline_run "$out" "$@"; }

: > "$out/commands.txt"
run "$binary" encode_images --image_path "$workspace/images" --output_path "$out/images" \
  --model "$model" --message "$message" | tee "$out/encode.txt"
run "$binary" train --workspace_path "$workspace" --image_path "$out/images" \
  --output_path "$out/model" --iterations "$iterations" --downscale "$downscale" --split train
run "$binary" extract --input_path "$out/model/point_cloud.ply" --workspace_path "$workspace" \
  --downscale "$downscale" --decoder "$model" --message "$message" --json "$out/extract.json"
echo "baseline_hidden_3dgs.sh: results in $out (encode.txt, extract.json)"
