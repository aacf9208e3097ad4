#!/usr/bin/env bash
# One point of a single-view curve (docs/history.md, "One view is enough"): embeds a trained
# model with --split train and the given options, then reads the 6 held-out views and FREE_VIEWS (48)
# free viewpoints one by one, blind and as the owner (extract --raw_path), and the held-out PSNR against
# the photos and against the raw model's renders. Appends one line to OUT/results.txt:
#   LABEL held MEAN% p90 P90% agg ERRORS [per-view errors] | free ... | owner: held ... | free ...
#     (first12 ...: the first 12 viewpoints alone, the sample of lines written before the probe read
#     48; the viewpoints are drawn in sequence, so they are the same 12) | PSNR vs photos dB |
#     vs raw dB | iterations, s | options
#   datasets_scripts/single_view_probe.sh OUT LABEL [embed options...]
# Environment: WATERGS_BIN, SCENE (workspace, default the demo scene), RAW (trained PLY; default
# OUT/raw/point_cloud.ply, trained here as run_demo.sh trains it), DECODER, DOWNSCALE (2),
# FREE_VIEWS (48; 12 before: two close-ups in those 12 set the second scene's mean), BACKGROUND
# (--background of every command, e.g. white for NeRF-synthetic; default black).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
out=${1:?usage: single_view_probe.sh OUT LABEL [embed options...]}; label=${2:?label}; shift 2
bin="${WATERGS_BIN:-$root/build/plugin/watergs}"
scene="${SCENE:-$root/datasets_scripts/demo_scene}"
decoder="${DECODER:-$root/watermark/models/decoder_48_residual_pool2.bin}"
ds="${DOWNSCALE:-2}"
raw="${RAW:-$out/raw/point_cloud.ply}"
free_views="${FREE_VIEWS:-48}"
background=(--background "${BACKGROUND:-black}")
msg=text:WGS-26
if [ ! -f "$raw" ]; then
  "$bin" train --workspace_path "$scene" --output_path "$(dirname "$raw")" --downscale "$ds" \
    --iterations 2000 --densify_until_iter 1000 --split train --test_iterations 2000 "${background[@]}" \
    > "$out/raw.log"
fi
run="$out/runs/$label"; mkdir -p "$run"
t0=$SECONDS
# A run stopped after its embedding (in the reads below) reads its kept wm.ply again.
if [ -f "$run/wm.ply" ] && [ -f "$run/embed_seconds" ] && grep -q "^embed: wrote $run/wm.ply" "$run/embed.log"; then
  seconds=$(cat "$run/embed_seconds")
else
  "$bin" embed --input_path "$raw" --workspace_path "$scene" --downscale "$ds" --decoder "$decoder" \
    --message "$msg" --output_path "$run/wm.ply" --split train "${background[@]}" "$@" > "$run/embed.log" 2>&1
  seconds=$((SECONDS - t0))
  echo "$seconds" > "$run/embed_seconds"
fi
read_views() {  # NAME [extract options]
  local name=$1; shift
  "$bin" extract --input_path "$run/wm.ply" --workspace_path "$scene" --downscale "$ds" \
    --decoder "$decoder" --message "$msg" --json "$run/$name.json" "${background[@]}" "$@" > "$run/$name.txt"
}
read_views held --split test --raw_path "$raw"
read_views free --num_views "$free_views" --seed 1 --raw_path "$raw"
# PSNR of the held-out views against the photos and against the raw renders (no attacks).
"$bin" eval --raw_path "$raw" --input_path "$run/wm.ply" --workspace_path "$scene" --downscale "$ds" \
  --decoder "$decoder" --message "$msg" --attacks '' --image_attacks '' --lpips_weights '' \
  "${background[@]}" --output_path "$run/eval" > "$run/eval.txt" 2>&1
/usr/bin/python3 - "$run" "$label" "$seconds" "$*" "$out/results.txt" <<'PY'
import json, re, sys
run, label, seconds, args, results = sys.argv[1:]
def views(name, reading=None):
    j = json.load(open(f"{run}/{name}.json"))
    if reading: j = j[reading]
    e = [v["bit_errors"] for v in j["views"]]
    p90 = sorted(e)[(9 * len(e) + 9) // 10 - 1]
    return e, 100 * sum(e) / len(e) / j["num_bits"], 100 * p90 / j["num_bits"], j["bit_errors"]
h, f = views("held"), views("free")
oh, of = views("held", "owner"), views("free", "owner")
first12 = 100 * sum(of[0][:12]) / min(12, len(of[0])) / json.load(open(f"{run}/free.json"))["num_bits"]
quality = {q["comparison"]: q["mean"]["psnr"] for q in json.load(open(f"{run}/eval.json"))["quality"]}
psnr = quality["watermarked vs ground truth"]; vs_raw = quality["watermarked vs raw renders"]
its = re.search(r"embed: (\d+) iterations", open(f"{run}/embed.log").read()).group(1)
line = (f"{label:24s} held {h[1]:5.1f}% p90 {h[2]:4.1f} agg {h[3]} {h[0]} | free {f[1]:5.1f}% p90 {f[2]:4.1f} "
        f"agg {f[3]} | owner held {oh[1]:5.1f}% p90 {oh[2]:4.1f} {oh[0]} | free{len(of[0])} {of[1]:5.1f}% p90 {of[2]:4.1f} "
        f"first12 {first12:4.1f}% "
        f"| PSNR {psnr:.2f} | vs raw {vs_raw:.2f} | {its} it {seconds}s | {args}")
print(line)
open(results, "a").write(line + "\n")
PY
