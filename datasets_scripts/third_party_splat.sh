#!/usr/bin/env bash
# A splat trained by another trainer, watermarked and read as a user would:
#   third_party_splat.sh SPLAT.ply WORKSPACE OUT [DOWNSCALE] [SEED]
# embed with nothing but the message (the shipped decoder, --split train: every 8th view held out of
# the embedding), then the owner's reading of each held-out view alone (extract --raw_path
# --split test), eval's held-out PSNR against the photos and against the splat's own renders,
# and the same splat taken as it is (--align off) for the "before" figure. Every command and
# its log land in OUT (commands.txt, *.log, *.json); OUT/summary.txt holds the figures.
set -euo pipefail
splat="${1:?usage: third_party_splat.sh SPLAT.ply WORKSPACE OUT [DOWNSCALE] [SEED]}"
ws="${2:?workspace}"
out="${3:?output folder}"
downscale="${4:-2}"
seed="${5:-0}"
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bin="${WATERGS_BIN:-$root/build/plugin/watergs}"
message='text:WGS-26'
mkdir -p "$out"
commit="$(git -C "$root" rev-parse HEAD 2>/dev/null || echo unknown)"
{ echo "# $(date -u +%FT%TZ) commit $commit on $(nproc) cores ($(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs))"; } >> "$out/commands.txt"
run() {
  local name="$1"; shift
  echo "watergs $*" >> "$out/commands.txt"
  local t0=$SECONDS
  "$bin" "$@" > "$out/$name.log" 2>&1
  echo "$name: $((SECONDS - t0)) s" >> "$out/times.txt"
}
wm="$out/watermarked_s$seed.ply"
common=(--workspace_path "$ws" --downscale "$downscale")
if [ ! -f "$wm" ]; then
  run "embed_s$seed" embed --input_path "$splat" "${common[@]}" --message "$message" \
    --output_path "$wm" --split train --seed "$seed" --checkpoint_every 250 \
    $( [ -f "$wm.ckpt" ] && echo --resume )
fi
run "extract_owner_s$seed" extract --input_path "$wm" --raw_path "$splat" "${common[@]}" \
  --message "$message" --split test --json "$out/extract_owner_s$seed.json"
run "eval_s$seed" eval --raw_path "$splat" --input_path "$wm" "${common[@]}" --message "$message" \
  --attacks identity --lpips_weights '' --output_path "$out/eval_s$seed"
run "eval_align_off_s$seed" eval --raw_path "$splat" --input_path "$wm" "${common[@]}" \
  --message "$message" --attacks identity --lpips_weights '' --align off \
  --output_path "$out/eval_align_off_s$seed"
python3 "$root/datasets_scripts/third_party_summary.py" "$out" "$seed"
