#!/usr/bin/env bash
# The README's main job on the embedded demo scene, end to end: train a 3DGS
# model (2,000 iterations at half resolution), embed a 48-bit WATER-GS
# watermark with the shipped decoder, attack the watermarked file (Gaussian
# noise, dropout, crop), then report the held-out PSNR cost and extract from
# each file (all 48 cameras; for the watermarked one also the 6 held-out
# views alone and 48 free viewpoints), printing the verdicts, and write the
# ownership report (OUTPUT_DIR/report.html). About 6 minutes on 2 idle cores
# (one of them the report).
#   scripts/run_demo.sh [OUTPUT_DIR]
# Environment: WATERGS_BIN (the CLI), DEMO_SCENE (another workspace whose
# images are 480x360), WATERGS_DECODER (decoder weights;
# default: the shipped decoder, watermark/models/decoder_48_residual_pool2.bin), DEMO_TRAIN_ITERS, DEMO_EMBED_ITERS.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
bin="${WATERGS_BIN:-$root/build/plugin/watergs}"
scene="${DEMO_SCENE:-$root/datasets_scripts/demo_scene}"
out="${1:-$root/build/demo}"
decoder="${WATERGS_DECODER:-$root/watermark/models/decoder_48_residual_pool2.bin}"
train_iters="${DEMO_TRAIN_ITERS:-2000}"
embed_iters="${DEMO_EMBED_ITERS:-1500}"
message="text:WGS-26"
mkdir -p "$out"
run() { echo "+ watergs $*"; "$bin" "$@"; }
start=$SECONDS

run model_info --sparse_path "$scene/sparse/0"

# Densification stops at half the run: this 240x180 scene needs ~40k
# Gaussians, and Inria's schedule (until 15k) is made for 30k iterations.
run train --workspace_path "$scene" --output_path "$out/train" --downscale 2 \
  --iterations "$train_iters" --densify_until_iter $((train_iters / 2)) \
  --split train --test_iterations "$train_iters"
raw="$out/train/point_cloud.ply"

# embed's defaults (whole frames, half of the iterations from free
# viewpoints, a logit margin, no density control): --split train only holds out
# every 8th view so that the held-out rows below read views it never saw.
run embed --input_path "$raw" --workspace_path "$scene" --downscale 2 \
  --decoder "$decoder" --message "$message" --output_path "$out/wm.ply" \
  --iterations "$embed_iters" --split train

for attack in gn:0.01 dropout:0.1 crop:0.1; do
  run attack --input_path "$out/wm.ply" --attack "$attack" \
    --output_path "$out/wm_${attack%%:*}.ply"
done

# Held-out PSNR against the ground truth: the watermark's cost.
psnr() {
  run render --input_path "$1" --workspace_path "$scene" --downscale 2 \
    --output_path "$out/render_$2" --split test | tee "$out/render_$2.txt" >&2
  grep -o 'mean PSNR [0-9.]* dB' "$out/render_$2.txt" | grep -o '[0-9.]*' | head -1
}
raw_psnr=$(psnr "$raw" raw)
wm_psnr=$(psnr "$out/wm.ply" wm)

summary=()
add_summary() {  # NAME TEXT_FILE: the owner's reading (when read) then the blind one; aggregated, then single views
  local blind owner read
  blind=$(grep -v "owner's reading" "$2")
  read="$blind"
  grep -q "owner's reading" "$2" && read=$(grep "owner's reading" "$2")
  line=$(printf '%-18s %s | %s | one view: %s' "$1" \
    "$(grep -o 'BER [0-9.]*%' <<< "$read" | head -1)" \
    "$(grep -o 'verdict: [a-z ]*' <<< "$read" | head -1 | sed 's/ *$//')" \
    "$(grep -o 'BER mean [0-9.]*% median [0-9.]*% p90 [0-9.]*%' <<< "$read")")
  if [ "$read" != "$blind" ]; then
    line+=" | blind: $(grep -o 'BER [0-9.]*%' <<< "$blind" | head -1), $(grep -o 'verdict: [a-z ]*' <<< "$blind" |
      sed 's/verdict: //; s/ *$//'), one view $(grep -o 'BER mean [0-9.]*%' <<< "$blind" | sed 's/BER //')"
  fi
  summary+=("$line")
}
# Each file read blind (its renders alone) and as the owner (minus the raw model's renders).
for name in raw wm wm_gn wm_dropout wm_crop; do
  ply="$out/$name.ply" owner=(--raw_path "$raw")
  [[ "$name" == raw ]] && ply="$raw" owner=()
  run extract --input_path "$ply" --workspace_path "$scene" --downscale 2 \
    --decoder "$decoder" --message "$message" "${owner[@]}" \
    --json "$out/extract_$name.json" | tee "$out/extract_$name.txt"
  add_summary "$name" "$out/extract_$name.txt"
done
# The held-out views (every 8th), unseen in training and embedding.
run extract --input_path "$out/wm.ply" --workspace_path "$scene" --downscale 2 \
  --decoder "$decoder" --message "$message" --split test --raw_path "$raw" \
  --json "$out/extract_wm_heldout.json" | tee "$out/extract_wm_heldout.txt"
add_summary "wm (6 held-out)" "$out/extract_wm_heldout.txt"
run extract --input_path "$out/wm.ply" --workspace_path "$scene" --downscale 2 \
  --decoder "$decoder" --message "$message" --num_views 48 --seed 1 --raw_path "$raw" \
  --json "$out/extract_wm_free.json" | tee "$out/extract_wm_free.txt"
add_summary "wm (48 free views)" "$out/extract_wm_free.txt"
# The watermark's cost on the held-out views: PSNR against the photos and against the raw renders.
run eval --raw_path "$raw" --input_path "$out/wm.ply" --workspace_path "$scene" --downscale 2 \
  --decoder "$decoder" --message "$message" --attacks '' --image_attacks '' --lpips_weights '' \
  > "$out/eval_fidelity.md"
vs_raw=$(grep '^| watermarked vs raw renders' "$out/eval_fidelity.md" | cut -d'|' -f3 | tr -d ' ')

# The ownership report an owner hands over: one HTML file with the claim on
# all 48 cameras, renders, BER per view, eval's attacks and the attacked files.
run report --raw_path "$raw" --input_path "$out/wm.ply" --workspace_path "$scene" \
  --downscale 2 --decoder "$decoder" --message "$message" \
  --copies "$out/wm_gn.ply,$out/wm_dropout.ply,$out/wm_crop.ply" \
  --output_path "$out/report.html"

echo
echo "== demo summary (message '$message', decoder $decoder, $((SECONDS - start)) s)"
echo "   each row: the owner's reading (minus the raw model's renders) where the file was read so, then blind"
printf '%s\n' "${summary[@]}"
echo "held-out PSNR vs the photos: raw $raw_psnr dB, watermarked $wm_psnr dB; watermarked vs the raw renders: $vs_raw dB"
echo "ownership report: $out/report.html"
