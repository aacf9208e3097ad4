#!/usr/bin/env bash
# The paper's Table 1 and the single-view figures on one real scene (an LLFF workspace laid out by
# download_llff.sh), at settings that finish on 2 cores: trains the raw model once (--split train: every
# 8th photo held out), then for each embedding run READING:SEED (READING:SEED:M adds
# --stop_margin M) embeds with embed's defaults for that reading (single_view_probe.sh: the
# held-out views and 12 free viewpoints read one by one, PSNR against the photos and against the
# raw renders) and evaluates the paper's four 3D distortions on the held-out views (eval: BER per
# rendered image, PSNR, SSIM). Resumable: every finished step is kept and skipped on a re-run (the
# training checkpoints every 500 iterations).
# Each run's file is also read blind over every camera of the workspace together (all_blind.json).
#   datasets_scripts/real_scene_tables.sh SCENE OUT [RUN ...]   (default runs: both:0 both:1 both:2 blind:0;
#   both is embed's default reading)
# A RUN of READING:SEED:STOP:NAME:EMBED ARGS (STOP may be empty) is an ablation: label
# READING_seedSEED_NAME, the words after the fourth colon added to embed's options, e.g.
#   'owner:0::nodl:--distortions none'   'owner:0::xyz:--mask xyz --distortions none'
# Writes OUT/tables.md (aggregate_real_scene.py) and OUT/times.txt (seconds per stage).
# Environment: WATERGS_BIN, DECODER, DOWNSCALE (2), ITERATIONS (7000; densification to half of it),
# EMBED_ARGS (extra embed options for every run, e.g. --stop_margin 1), ATTACK_DRAWS (1: draws of
# each random distortion in Table 1; above 1 a kept table1.json with another count is evaluated again),
# BACKGROUND (--background of every command: white for NeRF-synthetic; default black), INIT_ARGS
# (extra train options, e.g. --sh_degree 3).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
scene=${1:?usage: real_scene_tables.sh SCENE OUT [READING:SEED ...]}
out=${2:?usage: real_scene_tables.sh SCENE OUT [READING:SEED ...]}
shift 2
runs=("$@")
[ ${#runs[@]} -eq 0 ] && runs=(both:0 both:1 both:2 blind:0)
bin="${WATERGS_BIN:-$root/build/plugin/watergs}"
decoder="${DECODER:-$root/watermark/models/decoder_48_residual_pool2.bin}"
ds="${DOWNSCALE:-2}"
iterations="${ITERATIONS:-7000}"
draws="${ATTACK_DRAWS:-1}"
msg=text:WGS-26
background=(--background "${BACKGROUND:-black}")
export BACKGROUND="${BACKGROUND:-black}"
[ -d "$scene/images" ] || { echo "real_scene_tables: $scene/images: no such folder" >&2; exit 1; }
mkdir -p "$out"
raw="$out/raw/point_cloud.ply"
log() { echo "real_scene_tables: $*" >&2; }
timed() {  # STAGE COMMAND...: runs it, appends "STAGE SECONDS" to OUT/times.txt
  local stage=$1 t0=$SECONDS; shift
  "$@"
  echo "$stage $((SECONDS - t0))" >> "$out/times.txt"
}

if [ ! -f "$raw" ]; then
  resume=()
  [ -f "$out/raw/checkpoint.ckpt" ] && resume=(--resume)
  log "training the raw model ($iterations iterations, downscale $ds) -> $out/raw (log $out/raw.log)"
  timed train "$bin" train --workspace_path "$scene" --output_path "$out/raw" --downscale "$ds" --split train \
    --iterations "$iterations" --densify_until_iter $((iterations / 2)) --checkpoint_every 500 \
    --test_iterations "$((iterations / 2)),$iterations" --log_every 100 "${background[@]}" ${INIT_ARGS:-} \
    "${resume[@]}" >> "$out/raw.log" 2>&1
fi

for run in "${runs[@]}"; do
  IFS=: read -r reading seed stop name extra <<< "$run"
  label="${reading}_seed$seed"
  stop_args=()
  if [ -n "$stop" ]; then
    label+="_stop$stop"
    stop_args=(--stop_margin "$stop")
  fi
  read -r -a extra_args <<< "${extra:-}"
  [ -n "${name:-}" ] && label+="_$name"
  dir="$out/probe/runs/$label"
  if ! grep -q "^$label " "$out/probe/results.txt" 2>/dev/null; then
    log "embedding $label (log $dir/embed.log)"
    # shellcheck disable=SC2086
    timed "embed+read:$label" env SCENE="$scene" RAW="$raw" DOWNSCALE="$ds" DECODER="$decoder" \
      WATERGS_BIN="$bin" bash "$root/datasets_scripts/single_view_probe.sh" "$out/probe" "$label" \
      --reading "$reading" --seed "$seed" "${stop_args[@]}" "${extra_args[@]}" ${EMBED_ARGS:-}
  fi
  if [ ! -f "$dir/table1.json" ] ||
     { [ "$draws" -gt 1 ] && ! grep -q "\"attack_draws\": $draws," "$dir/table1.json"; }; then
    log "Table 1 distortions for $label"
    timed "eval:$label" "$bin" eval --raw_path "$raw" --input_path "$dir/wm.ply" --workspace_path "$scene" \
      --downscale "$ds" --decoder "$decoder" --message "$msg" --split test \
      --attacks identity,gn:0.01,dropout:0.1,crop:0.1 --image_attacks '' --lpips_weights '' \
      --attack_draws "$draws" "${background[@]}" \
      --output_path "$dir/table1" > "$dir/table1.txt" 2>&1
  fi
  if [ ! -f "$dir/all_blind.json" ]; then
    log "reading $label blind over every camera together"
    timed "all_blind:$label" "$bin" extract --input_path "$dir/wm.ply" --workspace_path "$scene" \
      --downscale "$ds" --decoder "$decoder" --message "$msg" "${background[@]}" \
      --json "$dir/all_blind.json" > "$dir/all_blind.txt" 2>&1
  fi
done
/usr/bin/python3 "$root/datasets_scripts/aggregate_real_scene.py" "$out" > "$out/tables.md.part"
mv "$out/tables.md.part" "$out/tables.md"
log "wrote $out/tables.md"
