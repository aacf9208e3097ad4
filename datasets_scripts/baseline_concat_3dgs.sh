#!/usr/bin/env bash
# The "CONCAT + 3DGS" baseline of the paper (Sec. 3 and 5): an explicit encoder writes the message
# into the SH coefficients of a trained 3DGS model (watergs concat_embed), and the model is evaluated
# as WATER-GS's are (watergs eval on the held-out views). The paper's finding to check: explicit
# offsets to the SH coefficients cost much more rendering quality than WATER-GS's fine-tuning, and
# read the message less reliably.
set -euo pipefail

usage() {
  cat <<'USAGE'
Usage: datasets_scripts/baseline_concat_3dgs.sh --decoder WEIGHTS --out DIR [options]

Writes, under DIR:
  raw/               the raw 3DGS model (train --split train), unless --raw is given
  watermarked.ply    the raw model with SH offsets from the trained encoder (concat_embed)
  concat_embed.txt   concat_embed's log: BER and PSNR on a few training views
  eval.json, eval.md watergs eval of the watermarked model against the raw one
  commands.txt       the exact commands run

Options:
  --decoder FILE         decoder weights (train_decoder's output, e.g. watermark/models/decoder_48.bin)
  --out DIR              output folder
  --raw PLY              a trained raw model (skips training)
  --workspace DIR        COLMAP workspace (default datasets_scripts/demo_scene)
  --binary PATH          watergs executable (default build/plugin/watergs)
  --message TEXT         message (default text:WGS-26)
  --train_iterations N   3DGS training iterations when training (default 30000)
  --iterations N         encoder training iterations (default 2000)
  --attributes A         SH groups the encoder writes: f_dc, f_rest or sh (default sh)
  --gamma G              weight of the message loss (default 0.3)
  --downscale D          image downscale for training, embedding and evaluation (default 1)
  --num_threads N        threads (default 0 = all cores)
USAGE
}

decoder="" out="" raw="" workspace=datasets_scripts/demo_scene binary=build/plugin/watergs
message=text:WGS-26 train_iterations=30000 iterations=2000 attributes=sh gamma=0.3 downscale=1
num_threads=0
while [[ $# -gt 0 ]]; do
  case "$1" in
    --decoder) decoder="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    --raw) raw="$2"; shift 2 ;;
    --workspace) workspace="$2"; shift 2 ;;
    --binary) binary="$2"; shift 2 ;;
    --message) message="$2"; shift 2 ;;
    --train_iterations) train_iterations="$2"; shift 2 ;;
    --iterations) iterations="$2"; shift 2 ;;
    --attributes) attributes="$2"; shift 2 ;;
    --gamma) gamma="$2"; shift 2 ;;
    --downscale) downscale="$2"; shift 2 ;;
    --num_threads) num_threads="$2"; shift 2 ;;
    -h|--help) usage; exit 0 ;;
    *) echo "baseline_concat_3dgs.sh: unknown option $1" >&2; usage >&2; exit 2 ;;
  esac
done
[[ -n "$decoder" && -n "$out" ]] || { usage >&2; exit 2; }
mkdir -p "$out"
source "$(dirname "${BASH_SOURCE[0]}")/lib_baseline.sh"
run() { baseline_run "$out" "$@"; }

: > "$out/commands.txt"
if [[ -z "$raw" ]]; then
  run "$binary" train --workspace_path "$workspace" --output_path "$out/raw" \
    --iterations "$train_iterations" --downscale "$downscale" --num_threads "$num_threads" --split train
  raw="$out/raw/point_cloud.ply"
fi
run "$binary" concat_embed --input_path "$raw" --workspace_path "$workspace" \
  --downscale "$downscale" --decoder "$decoder" --message "$message" \
  --output_path "$out/watermarked.ply" --iterations "$iterations" --attributes "$attributes" \
  --gamma "$gamma" --num_threads "$num_threads" --split train | tee "$out/concat_embed.txt"
run "$binary" eval --raw_path "$raw" --input_path "$out/watermarked.ply" \
  --workspace_path "$workspace" --downscale "$downscale" --decoder "$decoder" \
  --message "$message" --num_threads "$num_threads" --output_path "$out/eval"
echo "baseline_concat_3dgs.sh: results in $out (concat_embed.txt, eval.json, eval.md)"
