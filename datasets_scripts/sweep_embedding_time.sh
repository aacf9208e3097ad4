#!/usr/bin/env bash
# What WATER-GS embedding accuracy costs in time: embeds a watermark into one raw 3DGS model
# for every point of a grid (fine-tuning iterations x crop size x distortion layers on/off x
# message length), evaluates each result (BER under identity/gn/dropout/crop, PSNR against the
# raw renders) and writes a CSV with the Pareto fronts and a PNG of BER and PSNR against time.
set -euo pipefail

usage() {
  cat <<'EOF'
Usage: datasets_scripts/sweep_embedding_time.sh [options]

For each grid point: `watergs embed` (timed as a whole command), then `watergs eval` on the
held-out views with --attacks identity,gn:0.01,dropout:0.1,crop:0.1 (no image attacks, no
LPIPS). Writes, under OUT:
  embedding.csv   setting, iterations, crop_size, distortions, num_bits, embed_seconds,
                  iterations_run, gaussians, psnr_vs_raw, ssim_vs_raw, psnr_vs_gt,
                  raw_psnr_vs_gt, ber_identity, ber_gn, ber_dropout, ber_crop, ber_mean, ber_raw,
                  pareto_ber (front of time vs mean BER), pareto_psnr (time vs PSNR vs raw),
                  pareto_all (not dominated in time, mean BER and PSNR together),
                  load_avg_after (1-minute load average when the embed ended)
  embedding.png   BER (per attack, mean, front) and PSNR vs raw against embedding time
  commands.txt    the exact commands run
  points/<name>.json, points/<name>.eval.md   per point: timing, options and eval's JSON
  raw/            the raw model trained by this script (unless --raw_path is given)

Options:
  --workspace DIR       COLMAP workspace (default datasets_scripts/demo_scene)
  --binary PATH         watergs executable (default build/plugin/watergs)
  --out DIR             output folder (default results/accuracy_vs_time/embedding)
  --downscale D         image downscale for train, embed and eval (default 4)
  --raw_path PLY        raw model to watermark; default: train one with --split train
  --raw_iterations N    iterations of that raw model (default 2000)
  --decoders LIST       decoders L:PATH,... by message length L (bits); each length is a
                        grid axis value (default 48:watermark/models/decoder_48.bin)
  --iterations LIST     fine-tuning iterations (default 50,100,200)
  --crop_sizes LIST     embed --crop_size values, 0 = whole frames (default 64,0)
  --distortions LIST    on (identity,gn:0.01,dropout:0.1,crop:0.1) and/or off (default on,off)
  --threads T           --num_threads for every command (default 1)
  --seed S              --seed for every command (default 0)
  --embed_args "ARGS"   further embed options for every point, e.g. "--gamma 0.03
                        --free_view_fraction 0.5 --densify off" (word-split)
  --keep_models         keep the watermarked PLYs (deleted otherwise)
  -h, --help            this text

All commands run under `nice -n 10`. The message for length L is a fixed pseudo-random bit
string (Python random.Random(L)), written to commands.txt.
EOF
}

die() { echo "sweep_embedding_time: $*" >&2; exit 1; }

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
workspace="$root/datasets_scripts/demo_scene"
binary="$root/build/plugin/watergs"
out="$root/results/accuracy_vs_time/embedding"
downscale=4
raw_path=""
raw_iterations=2000
decoders="48:$root/watermark/models/decoder_48.bin"
iterations_list="50,100,200"
crop_list="64,0"
distortion_list="on,off"
threads=1
seed=0
keep_models=0
embed_args=""
while [ $# -gt 0 ]; do
  case "$1" in
    --workspace) workspace="${2:?--workspace needs a value}"; shift 2 ;;
    --binary) binary="${2:?--binary needs a value}"; shift 2 ;;
    --out) out="${2:?--out needs a value}"; shift 2 ;;
    --downscale) downscale="${2:?--downscale needs a value}"; shift 2 ;;
    --raw_path) raw_path="${2:?--raw_path needs a value}"; shift 2 ;;
    --raw_iterations) raw_iterations="${2:?--raw_iterations needs a value}"; shift 2 ;;
    --decoders) decoders="${2:?--decoders needs a value}"; shift 2 ;;
    --iterations) iterations_list="${2:?--iterations needs a value}"; shift 2 ;;
    --crop_sizes) crop_list="${2:?--crop_sizes needs a value}"; shift 2 ;;
    --distortions) distortion_list="${2:?--distortions needs a value}"; shift 2 ;;
    --threads) threads="${2:?--threads needs a value}"; shift 2 ;;
    --seed) seed="${2:?--seed needs a value}"; shift 2 ;;
    --keep_models) keep_models=1; shift ;;
    --embed_args) embed_args="${2?--embed_args needs a value}"; shift 2 ;;
    -h|--help) usage; exit 0 ;;
    *) usage >&2; die "unknown option '$1'" ;;
  esac
done

source "$(dirname "${BASH_SOURCE[0]}")/lib_sweep.sh"
require_watergs_workspace "$binary" "$workspace"
[[ "$downscale" =~ ^(1|2|4|8)$ ]] || die "--downscale '$downscale': expected 1, 2, 4 or 8"
[[ "$raw_iterations" =~ ^[1-9][0-9]*$ ]] || die "--raw_iterations '$raw_iterations': not a positive integer"
[[ "$threads" =~ ^[0-9]+$ ]] || die "--threads '$threads': not a non-negative integer"
[[ "$iterations_list" =~ ^[1-9][0-9]*(,[1-9][0-9]*)*$ ]] || die "--iterations '$iterations_list': expected positive integers, comma-separated"
[[ "$crop_list" =~ ^[0-9]+(,[0-9]+)*$ ]] || die "--crop_sizes '$crop_list': expected integers, comma-separated"
[[ "$distortion_list" =~ ^(on|off)(,(on|off))*$ ]] || die "--distortions '$distortion_list': expected on and/or off"
[ -z "$raw_path" ] || [ -f "$raw_path" ] || die "$raw_path: no such raw model"
command -v python3 >/dev/null || die "python3 not found"
plot="$root/datasets_scripts/pareto_plot.py"

# Decoders by message length L (L:PATH items); each length is a grid axis value.
declare -A decoder_by_len=()
lengths=()
IFS=',' read -r -a items <<<"$decoders"
for item in "${items[@]}"; do
  [[ "$item" =~ ^([1-9][0-9]*):(.+)$ ]] || die "--decoders item '$item': expected L:PATH"
  len="${BASH_REMATCH[1]}"; path="${BASH_REMATCH[2]}"
  [ -f "$path" ] || die "$path: no such decoder file (--decoders $item)"
  [ -z "${decoder_by_len[$len]:-}" ] || die "--decoders: two decoders for length $len"
  decoder_by_len[$len]="$path"
  lengths+=("$len")
done
[ ${#lengths[@]} -gt 0 ] || die "--decoders: no decoder given"
message_for() {  # a fixed pseudo-random message of $1 bits
  python3 -c "import random,sys; n=int(sys.argv[1]); r=random.Random(n); print('bits:'+''.join(str(r.getrandbits(1)) for _ in range(n)))" "$1"
}

mkdir -p "$out/points"
commands="$out/.commands.txt.tmp"
rel() { sed -e "s#$root/##g"; }
{
  echo "# $(date -u +%FT%TZ) on $(hostname), $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg)"
  echo "# datasets_scripts/sweep_embedding_time.sh --workspace $workspace --downscale $downscale --iterations $iterations_list --crop_sizes $crop_list --distortions $distortion_list --threads $threads --seed $seed --decoders $decoders${raw_path:+ --raw_path $raw_path}" | rel
} >"$commands"

# The raw model: given, or trained here (held-out views kept out, as eval expects).
if [ -z "$raw_path" ]; then
  raw_dir="$out/raw"
  rm -rf "$raw_dir.partial"
  cmd=(nice -n 10 "$binary" train --device cpu --workspace_path "$workspace" --output_path "$raw_dir.partial"
    --downscale "$downscale" --iterations "$raw_iterations" --split train
    --test_iterations "$raw_iterations" --num_threads "$threads" --seed "$seed")
  echo "${cmd[*]}" | sed -e "s#$raw_dir.partial#$raw_dir#" | rel >>"$commands"
  echo "sweep_embedding_time: training the raw model ($(date -u +%T))" >&2
  "${cmd[@]}" >"$raw_dir.partial.log" 2>&1 || die "train failed (see $raw_dir.partial.log)"
  rm -f "$raw_dir.partial/checkpoint.ckpt"
  mv "$raw_dir.partial.log" "$raw_dir.partial/train_output.txt"
  rm -rf "$raw_dir"
  mv "$raw_dir.partial" "$raw_dir"
  raw_path="$raw_dir/point_cloud.ply"
fi

IFS=',' read -r -a iteration_values <<<"$iterations_list"
IFS=',' read -r -a crop_values <<<"$crop_list"
IFS=',' read -r -a distortion_values <<<"$distortion_list"
attacks="identity,gn:0.01,dropout:0.1,crop:0.1"
points=()
for len in "${lengths[@]}"; do
  dec="${decoder_by_len[$len]}"
  message=$(message_for "$len")
  echo "# message for $len bits: $message" >>"$commands"
  for dist in "${distortion_values[@]}"; do
    if [ "$dist" = on ]; then dist_arg="$attacks"; else dist_arg=none; fi
    for crop in "${crop_values[@]}"; do
      for iters in "${iteration_values[@]}"; do
        name="L${len}_dist${dist}_crop${crop}_it${iters}"
        wm="$out/points/$name.ply"
        tmp_wm="$out/points/.$name.partial.ply"
        rm -f "$tmp_wm" "$tmp_wm.ckpt"
        cmd=(nice -n 10 "$binary" embed --device cpu --input_path "$raw_path" --workspace_path "$workspace"
          --downscale "$downscale" --decoder "$dec" --message "$message" --output_path "$tmp_wm"
          --iterations "$iters" --crop_size "$crop" --distortions "$dist_arg"
          --num_threads "$threads" --seed "$seed" --split train --reading blind)
        # shellcheck disable=SC2206  # word-split on purpose
        [ -z "$embed_args" ] || cmd+=($embed_args)
        echo "${cmd[*]}" | sed -e "s#$tmp_wm#$wm#" | rel >>"$commands"
        echo "sweep_embedding_time: $name ($(date -u +%T))" >&2
        t0=$(date +%s.%N)
        "${cmd[@]}" >"$out/points/.$name.embed.txt" 2>&1 || die "embed failed for $name (see $out/points/.$name.embed.txt)"
        t1=$(date +%s.%N)
        mv "$tmp_wm" "$wm"
        ecmd=(nice -n 10 "$binary" eval --device cpu --raw_path "$raw_path" --input_path "$wm"
          --workspace_path "$workspace" --downscale "$downscale" --decoder "$dec"
          --message "$message" --output_path "$out/points/.$name.eval" --attacks "$attacks"
          --image_attacks '' --lpips_weights '' --num_threads "$threads" --seed "$seed")
        echo "${ecmd[*]}" | sed -e "s#/\.$name\.eval#/$name.eval#" -e "s#--image_attacks  #--image_attacks '' #" \
          -e "s#--lpips_weights  #--lpips_weights '' #" | rel >>"$commands"
        "${ecmd[@]}" >/dev/null 2>"$out/points/.$name.eval.err" || die "eval failed for $name (see $out/points/.$name.eval.err)"
        python3 - "$out/points/$name.json" "$out/points/.$name.eval.json" "$out/points/.$name.embed.txt" \
          "$name" "$iters" "$crop" "$dist" "$len" "$t0" "$t1" <<'PY'
import json, os, re, sys
path, eval_path, embed_log, name, iters, crop, dist, bits, t0, t1 = sys.argv[1:]
with open(eval_path) as f:
    ev = json.load(f)
text = open(embed_log, errors="replace").read()
m = re.search(r"embed: (\d+) iterations in", text)
point = {"setting": "%s bits, distortions %s, crop %s, %s it" % (bits, dist, crop if crop != "0" else "frame", iters),
         "name": name, "iterations": int(iters), "crop_size": int(crop), "distortions": dist,
         "num_bits": int(bits), "embed_seconds": round(float(t1) - float(t0), 3),
         "iterations_run": int(m.group(1)) if m else None,
         "embed_summary": [l for l in text.splitlines() if l.startswith("embed:")],
         "load_avg_after": float(open("/proc/loadavg").read().split()[0]),
         "eval": ev}
with open(path + ".tmp", "w") as f:
    json.dump(point, f, indent=1)
os.replace(path + ".tmp", path)
PY
        mv "$out/points/.$name.eval.md" "$out/points/$name.eval.md"
        rm -f "$out/points/.$name.eval.json" "$out/points/.$name.eval.err" "$out/points/.$name.embed.txt"
        [ "$keep_models" = 1 ] || rm -f "$wm"
        points+=("$out/points/$name.json")
      done
    done
  done
done

python3 "$plot" embed-csv "${points[@]}" --out "$out/embedding.csv"
python3 "$plot" plot-embed "$out/embedding.csv" --png "$out/embedding.png" \
  --title "WATER-GS embedding on $(basename "$workspace") (1/$downscale res): BER and PSNR against wall time"
echo "# finished $(date -u +%FT%TZ)" >>"$commands"
mv "$commands" "$out/commands.txt"
echo "sweep_embedding_time: wrote $out/embedding.csv, $out/embedding.png" >&2
