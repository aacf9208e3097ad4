#!/usr/bin/env bash
# Reproduces the WATER-GS paper's tables with the watergs CLI: trains each raw 3DGS model once, embeds
# watermarks under the paper's settings and evaluates them on the held-out views (every 8th image):
#   (a) robustness: BER under Identity / GN / Dropout / Crop per scene and per dataset (Table 1 shape)
#   (b) ablation on the 3D distortion layers (with vs without, BER and PSNR under each distortion)
#   (c) embedding positions (xyz, f_dc, f_rest, ALL; without distortion layers, as the paper's table)
#   (d) message lengths (one decoder per length, with distortion layers)
#   (e) wall time of training and embedding
# Every step is cached under OUT/work/ (a rerun skips finished steps, so the script can be interrupted);
# OUT/tables.md, OUT/results.csv and OUT/commands.txt are written atomically at the end by aggregate_tables.py.
# With --slurm, one Slurm array task per scene runs that scene's steps and a dependent job aggregates
# (the submission code of scripts/slurm/watergs_batch.sh).
set -euo pipefail

script_name="$(basename "$0")"
script_dir="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
repo_root="$(cd "$script_dir/.." && pwd)"
# shellcheck source=lib_steps.sh
source "$script_dir/lib_steps.sh"
# shellcheck source=../scripts/slurm/lib_slurm.sh
source "$repo_root/scripts/slurm/lib_slurm.sh"

usage() {
  cat <<EOF
Usage: bash datasets_scripts/$script_name [options] [WORKSPACE ...]

Scenes: COLMAP workspaces (WORKSPACE/sparse/0 and WORKSPACE/images) given as arguments, and/or
  --dataset llff|mipnerf360|tandt DIR   the paper's scenes of that dataset found under DIR (laid out by
                                        datasets_scripts/download_<dataset>.sh); absent scenes are skipped
  With neither, the two offline scenes datasets_scripts/demo_scene and demo_scene_v2 are used.

Options:
  --output_path OUT         results folder (default results/reproduce)
  --bin PATH                watergs binary (default \$WATERGS_BIN or build/plugin/watergs)
  --train_iterations N      3DGS training iterations (default 30000)
  --embed_iterations N      watermark fine-tuning iterations (default 10000)
  --downscale D|auto        image downscale 1,2,4,8; auto (default): LLFF 8, Mip-NeRF 360 outdoor 4 /
                            indoor 2, Tanks&Temples 1, other workspaces 1
  --gamma G|auto            message-loss weight; auto (default): 0.1 for LLFF, 0.3 otherwise (the paper)
  --seeds LIST              comma-separated seeds (default 0,1,2); tables show mean ± std over them
  --decoder_for L:PATH      decoder for L-bit messages; repeat for the length table
                            (default 48:watermark/models/decoder_48.bin)
  --crop_size N             embed crop side (default 128)
  --embed_args "ARGS"       further embed options for every run, word-split, e.g. the demo's
                            "--free_view_fraction 0.5 --densify off" (crop and gamma:
                            this script's --crop_size 0 --gamma 0.03)
  --lpips_weights PATH      LPIPS-VGG weights (default data/lpips/lpips_vgg.bin; column empty if absent)
  --num_threads N           threads per watergs call (default 0 = all cores)
  --note TEXT               line written at the top of tables.md
  --baseline NAME=JSON      a baseline run's extract/eval JSON (e.g. from baseline_hidden_3dgs.sh),
                            checked in claims.md against the paper's claim that baselines fail; repeatable
  -h, --help                this text

On a Slurm cluster (docs/batch.md):
  --slurm                   submit one array task per scene that still has steps to run, and a job that
                            aggregates after them (afterany); with none left, aggregate here. The same
                            command again resubmits only unfinished scenes (finished steps are cached)
  --wait                    with --slurm: wait for the aggregate job and print where the tables are
  --scene_index K           run only scene K's steps (0-based, in the order above), no tables; an array
                            task's index when K is 'task' (\$SLURM_ARRAY_TASK_ID, \$JOB_COMPLETION_INDEX)
  --aggregate_only          run no step: tables from the finished runs (unfinished ones are left out)
EOF
  slurm_options_usage | sed 's/^/  /'
}

log() { echo "[$(date -u +%H:%M:%S)] $*"; }
die() {
  echo "$script_name: error: $*" >&2
  exit 1
}

readonly original_args=("$@")
bin="${WATERGS_BIN:-$repo_root/build/plugin/watergs}"
out_dir="results/reproduce"
train_iterations=30000
embed_iterations=10000
downscale_option=auto
gamma_option=auto
seeds_option=0,1,2
crop_size=128
embed_args=""
lpips_weights="$repo_root/data/lpips/lpips_vgg.bin"
num_threads=0
note=""
decoder_specs=()
baseline_args=()    # --baseline NAME=JSON pairs for check_claims.py
forward_args=()     # the arguments an array task gets (all but the Slurm ones)
slurm="" slurm_wait_for="" scene_index="" step_mode=run  # step_mode: run, check (count missing steps), skip
scenes=()           # each: dataset|label|workspace|downscale|gamma
datasets_asked=()   # each: dataset|dir

need_value() { [ "$2" -ge 2 ] || die "option $1 needs a value (see --help)"; }

while [ $# -gt 0 ]; do
  case "$1" in
    -h | --help) usage; exit 0 ;;
    --slurm) slurm=1; shift; continue ;;
    --wait) slurm_wait_for=1; shift; continue ;;
    --aggregate_only) step_mode=skip; shift; continue ;;
    --scene_index) need_value "$1" $#; scene_index="$2"; shift 2; continue ;;
    --dataset)
      [ $# -ge 3 ] || die "--dataset needs NAME and DIR"
      datasets_asked+=("$2|$3"); forward_args+=("$1" "$2" "$3"); shift 3; continue ;;
    --output_path) need_value "$1" $#; out_dir="$2" ;;
    --bin) need_value "$1" $#; bin="$2" ;;
    --train_iterations) need_value "$1" $#; train_iterations="$2" ;;
    --embed_iterations) need_value "$1" $#; embed_iterations="$2" ;;
    --downscale) need_value "$1" $#; downscale_option="$2" ;;
    --gamma) need_value "$1" $#; gamma_option="$2" ;;
    --seeds) need_value "$1" $#; seeds_option="$2" ;;
    --decoder_for) need_value "$1" $#; decoder_specs+=("$2") ;;
    --crop_size) need_value "$1" $#; crop_size="$2" ;;
    --embed_args) need_value "$1" $#; embed_args="$2" ;;
    --lpips_weights) need_value "$1" $#; lpips_weights="$2" ;;
    --num_threads) need_value "$1" $#; num_threads="$2" ;;
    --note) need_value "$1" $#; note="$2" ;;
    --baseline) need_value "$1" $#; baseline_args+=(--baseline "$2") ;;
    -*)
      slurm_take_option "$1" "${2-}" || die "unknown option '$1' (see --help)"
      need_value "$1" $#
      shift 2; continue ;;
    *) scenes+=("custom|$(basename "$1")|$1||"); forward_args+=("$1"); shift; continue ;;
  esac
  forward_args+=("$1" "$2")
  shift 2
done
slurm_check_options cpu
if [ "$scene_index" = task ]; then
  scene_index="${SLURM_ARRAY_TASK_ID:-${JOB_COMPLETION_INDEX:-}}"
  [ -n "$scene_index" ] || die "--scene_index task outside an array task (no SLURM_ARRAY_TASK_ID or JOB_COMPLETION_INDEX)"
fi
[ -z "$scene_index" ] || [[ "$scene_index" =~ ^[0-9]+$ ]] || die "--scene_index '$scene_index' is not a whole number"
# In an array task, "all cores" are the task's own.
[ "$num_threads" != 0 ] || [ -z "${SLURM_CPUS_PER_TASK:-}" ] || num_threads="$SLURM_CPUS_PER_TASK"

is_uint() { [[ "$1" =~ ^[0-9]+$ ]]; }
is_uint "$train_iterations" || die "--train_iterations '$train_iterations' is not a whole number"
is_uint "$embed_iterations" || die "--embed_iterations '$embed_iterations' is not a whole number"
is_uint "$num_threads" || die "--num_threads '$num_threads' is not a whole number"
is_uint "$crop_size" || die "--crop_size '$crop_size' is not a whole number"
[[ "$downscale_option" =~ ^(auto|1|2|4|8)$ ]] || die "--downscale '$downscale_option' is not auto, 1, 2, 4 or 8"
[[ "$gamma_option" =~ ^(auto|[0-9.]+)$ ]] || die "--gamma '$gamma_option' is not auto or a number"
[[ "$seeds_option" =~ ^[0-9]+(,[0-9]+)*$ ]] || die "--seeds '$seeds_option' is not a comma-separated list of seeds"
IFS=, read -r -a seeds <<<"$seeds_option"

[ -x "$bin" ] || die "watergs binary '$bin' not found or not executable (build it, or pass --bin / WATERGS_BIN)"
command -v python3 >/dev/null || die "python3 not found"

# Decoders: L -> path, sorted by length; the robustness and ablation tables use the longest (48 in the paper).
[ ${#decoder_specs[@]} -eq 0 ] && decoder_specs=("48:$repo_root/watermark/models/decoder_48.bin")
declare -A decoder_of=()
for spec in "${decoder_specs[@]}"; do
  [[ "$spec" =~ ^([0-9]+):(.+)$ ]] || die "--decoder_for '$spec' is not L:PATH"
  [ -f "${BASH_REMATCH[2]}" ] || die "decoder '${BASH_REMATCH[2]}' (for ${BASH_REMATCH[1]} bits) not found"
  decoder_of[${BASH_REMATCH[1]}]="$(cd "$(dirname "${BASH_REMATCH[2]}")" && pwd)/$(basename "${BASH_REMATCH[2]}")"
done
mapfile -t lengths < <(printf '%s\n' "${!decoder_of[@]}" | sort -n)
main_length="${lengths[-1]}"

# The paper's scenes of one dataset found under DIR; absent ones are reported and skipped.
add_dataset() {
  local dataset="$1" dir="$2" scene names ds gamma found=0
  case "$dataset" in
    llff) names=(fern flower fortress horns leaves orchids room trex) ;;
    mipnerf360) names=(bicycle bonsai counter garden kitchen room stump flowers treehill) ;;
    tandt) names=(train truck) ;;
    *) die "unknown dataset '$dataset' (known: llff mipnerf360 tandt)" ;;
  esac
  for scene in "${names[@]}"; do
    if [ ! -d "$dir/$scene/sparse/0" ]; then
      log "skip: $dataset scene '$scene' not present at $dir/$scene (bash datasets_scripts/download_$dataset.sh $dir)"
      continue
    fi
    case "$dataset/$scene" in
      llff/*) ds=8 gamma=0.1 ;;
      mipnerf360/bonsai | mipnerf360/counter | mipnerf360/kitchen | mipnerf360/room) ds=2 gamma=0.3 ;;
      mipnerf360/*) ds=4 gamma=0.3 ;;
      *) ds=1 gamma=0.3 ;;
    esac
    scenes+=("$dataset|$scene|$dir/$scene|$ds|$gamma")
    found=$((found + 1))
  done
  [ $found -gt 0 ] || log "skip: no $dataset scene found under $dir; the $dataset tables are left out"
}
for entry in "${datasets_asked[@]+"${datasets_asked[@]}"}"; do add_dataset "${entry%%|*}" "${entry#*|}"; done
if [ ${#scenes[@]} -eq 0 ] && [ ${#datasets_asked[@]} -eq 0 ]; then
  scenes=("offline|demo_scene|$script_dir/demo_scene||" "offline|demo_scene_v2|$script_dir/demo_scene_v2||")
fi
[ ${#scenes[@]} -gt 0 ] || die "no scene to run (every dataset asked for is absent)"
[ -z "$scene_index" ] || [ "$scene_index" -lt ${#scenes[@]} ] ||
  die "--scene_index $scene_index: there are ${#scenes[@]} scenes (0-$((${#scenes[@]} - 1)))"

declare -A label_seen=()
for entry in "${scenes[@]}"; do
  IFS='|' read -r dataset label workspace _ _ <<<"$entry"
  [ -d "$workspace/sparse/0" ] || die "workspace '$workspace' has no COLMAP model sparse/0"
  [ -d "$workspace/images" ] || die "workspace '$workspace' has no images/ folder"
  [ -z "${label_seen[$dataset/$label]:-}" ] || die "two scenes are both named '$dataset/$label'"
  label_seen[$dataset/$label]=1
done

mkdir -p "$out_dir/work"
out_dir="$(cd "$out_dir" && pwd)"
lpips_used=""
[ -f "$lpips_weights" ] && lpips_used="$lpips_weights"
[ -n "$lpips_used" ] || log "note: LPIPS weights '$lpips_weights' absent; the LPIPS columns stay empty"

commands_file="$(mktemp "$out_dir/.commands.XXXXXX")"
manifest_file="$(mktemp "$out_dir/.manifest.XXXXXX")"
trap 'rm -f "$commands_file" "$manifest_file"' EXIT
{
  echo "# $script_name invocation (cwd $(pwd)):"
  printf '%q ' bash "datasets_scripts/$script_name" "${original_args[@]+"${original_args[@]}"}"
  echo
  echo "# settings: train_iterations=$train_iterations embed_iterations=$embed_iterations downscale=$downscale_option" \
    "gamma=$gamma_option seeds=$seeds_option crop_size=$crop_size num_threads=$num_threads" \
    "decoders=$(for l in "${lengths[@]}"; do printf '%s:%s ' "$l" "${decoder_of[$l]#"$repo_root/"}"; done)"
  echo "# watergs commands (each run once; later invocations reuse the cached outputs):"
} >"$commands_file"

# Runs a watergs command unless DONE exists; then records its wall time (seconds) in DONE atomically.
# With step_mode check or skip, an unfinished step only counts in steps_missing.
steps_missing=0
run_step() {
  local done_file="$1" log_file="$2" what="$3"
  shift 3
  printf '%q ' "$@" | sed "s|^$bin |watergs |; s|$repo_root/||g; s|$out_dir/||g" >>"$commands_file"
  echo >>"$commands_file"
  if [ "$step_mode" != run ] && [ ! -f "$done_file" ]; then
    steps_missing=$((steps_missing + 1))
    [ "$step_mode" = check ] || log "not finished, left out: $what"
    return 0
  fi
  step_run "$done_file" "$log_file" "$what" "$@" || die "$what failed (log: $log_file)"
}

# Deterministic L-bit message for (L, seed), the same on every scene.
message_bits() {
  python3 -c "import random,sys; r=random.Random('watergs-%s-%s' % (sys.argv[1], sys.argv[2])); \
print(''.join(str(r.randint(0, 1)) for _ in range(int(sys.argv[1]))))" "$1" "$2"
}

# One embedding run: embed, evaluate under the four distortions; with ATTACKED_PSNR, also evaluate the
# attacked models themselves (the DL-ablation table's PSNR under each distortion).
embed_run() {
  local dataset="$1" label="$2" workspace="$3" ds="$4" gamma="$5" raw_dir="$6" settings_dir="$7"
  local mask="$8" dl="$9" length="${10}" seed="${11}" attacked_psnr="${12}"
  local run_dir="$settings_dir/${mask//,/+}-dl_$dl-L$length-s$seed"
  local distortions="identity,gn:0.01,dropout:0.1,crop:0.1" message decoder="${decoder_of[$length]}"
  [ "$dl" = on ] || distortions=none
  mkdir -p "$run_dir"
  message="bits:$(message_bits "$length" "$seed")"
  local what="$dataset/$label mask=$mask DL=$dl L=$length seed=$seed" missing_before=$steps_missing
  run_step "$run_dir/embed.seconds" "$run_dir/embed.log" "embed $what ($embed_iterations it)" \
    "$bin" embed --input_path "$raw_dir/point_cloud.ply" --workspace_path "$workspace" --downscale "$ds" \
    --decoder "$decoder" --message "$message" --output_path "$run_dir/watermarked.ply" \
    --iterations "$embed_iterations" --gamma "$gamma" --mask "$mask" --distortions "$distortions" \
    --crop_size "$crop_size" --seed "$seed" --num_threads "$num_threads" --split train --reading blind $embed_args
  run_step "$run_dir/eval.seconds" "$run_dir/eval.stdout" "eval $what" \
    "$bin" eval --raw_path "$raw_dir/point_cloud.ply" --input_path "$run_dir/watermarked.ply" \
    --workspace_path "$workspace" --downscale "$ds" --decoder "$decoder" --message "$message" \
    --attacks identity,gn:0.01,dropout:0.1,crop:0.1 --image_attacks '' --lpips_weights "$lpips_used" \
    --seed "$seed" --num_threads "$num_threads" --output_path "$run_dir/eval"
  if [ "$attacked_psnr" = yes ]; then
    local attack name
    for attack in gn:0.01 dropout:0.1 crop:0.1; do
      name="${attack%%:*}"
      if [ ! -f "$run_dir/attacked_$name.seconds" ]; then
        # The attacked PLY is deleted once evaluated; an attack whose PLY is gone before that is redone.
        [ -f "$run_dir/attacked_$name.ply" ] || rm -f "$run_dir/attack_$name.seconds"
        run_step "$run_dir/attack_$name.seconds" "$run_dir/attack_$name.log" "attack $attack $what" \
          "$bin" attack --input_path "$run_dir/watermarked.ply" --attack "$attack" --seed "$seed" \
          --output_path "$run_dir/attacked_$name.ply"
      fi
      run_step "$run_dir/attacked_$name.seconds" "$run_dir/attacked_$name.stdout" "eval $attack-attacked $what" \
        "$bin" eval --raw_path "$raw_dir/point_cloud.ply" --input_path "$run_dir/attacked_$name.ply" \
        --workspace_path "$workspace" --downscale "$ds" --decoder "$decoder" --message "$message" \
        --attacks identity --image_attacks '' --lpips_weights "$lpips_used" --seed "$seed" \
        --num_threads "$num_threads" --output_path "$run_dir/attacked_$name"
      # Large; once evaluated, the evaluation is what is kept (a check pass deletes nothing else).
      [ ! -f "$run_dir/attacked_$name.seconds" ] || rm -f "$run_dir/attacked_$name.ply"
    done
  fi
  [ "$steps_missing" -eq "$missing_before" ] || return 0  # unfinished: not in the tables
  printf '%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\n' "$dataset" "$label" "$mask" "$dl" "$length" "$seed" \
    "$run_dir" "$raw_dir" "$ds" >>"$manifest_file"
}

# Every step of one scene (run, checked or skipped by step_mode).
scene_steps() {
  local entry="$1" dataset label workspace ds gamma scene_dir raw_dir settings_dir seed mask length
  IFS='|' read -r dataset label workspace ds gamma <<<"$entry"
  [ "$downscale_option" = auto ] || ds="$downscale_option"
  [ -n "$ds" ] || ds=1
  [ "$gamma_option" = auto ] || gamma="$gamma_option"
  [ -n "$gamma" ] || gamma=0.3
  scene_dir="$out_dir/work/$dataset/$label"
  raw_dir="$scene_dir/raw_ds${ds}_it$train_iterations"
  mkdir -p "$raw_dir"
  [ "$step_mode" = check ] || log "scene $dataset/$label ($workspace, downscale $ds, gamma $gamma)"
  run_step "$raw_dir/train.seconds" "$raw_dir/train.stdout" "train $dataset/$label ($train_iterations it)" \
    "$bin" train --workspace_path "$workspace" --output_path "$raw_dir" --downscale "$ds" \
    --iterations "$train_iterations" --seed 0 --num_threads "$num_threads" --split train
  settings_dir="$raw_dir/embed_it${embed_iterations}_crop${crop_size}_gamma$gamma"
  for seed in "${seeds[@]}"; do
    # (a) robustness, (b) DL ablation "with", (d) the main length: ALL, with distortion layers.
    embed_run "$dataset" "$label" "$workspace" "$ds" "$gamma" "$raw_dir" "$settings_dir" ALL on "$main_length" "$seed" yes
    # (b) "w/o DL" and (c) the ALL row of the positions table.
    embed_run "$dataset" "$label" "$workspace" "$ds" "$gamma" "$raw_dir" "$settings_dir" ALL none "$main_length" "$seed" yes
    # (c) embedding positions, without distortion layers as in the paper's table.
    for mask in xyz f_dc f_rest; do
      embed_run "$dataset" "$label" "$workspace" "$ds" "$gamma" "$raw_dir" "$settings_dir" "$mask" none "$main_length" "$seed" no
    done
    # (d) the other message lengths, with distortion layers.
    for length in "${lengths[@]}"; do
      [ "$length" = "$main_length" ] && continue
      embed_run "$dataset" "$label" "$workspace" "$ds" "$gamma" "$raw_dir" "$settings_dir" ALL on "$length" "$seed" no
    done
  done
}

if [ -n "$scene_index" ]; then
  scene_steps "${scenes[$scene_index]}"
  log "scene $scene_index done; the tables come from a run without --scene_index (or --aggregate_only)"
  exit 0
fi

if [ -n "$slurm" ]; then
  # Scenes with unfinished steps, found by walking every scene's steps without running them.
  step_mode=check
  pending=""
  for k in "${!scenes[@]}"; do
    steps_missing=0
    scene_steps "${scenes[$k]}"
    [ "$steps_missing" -eq 0 ] || pending+="${pending:+,}$k"
  done
  step_mode=run
  if [ -n "$pending" ]; then
    sub="$out_dir/submissions/$(date -u +%Y%m%dT%H%M%SZ)-$$"
    mkdir -p "$sub"
    common=(bash "$script_dir/$script_name" "${forward_args[@]}" --output_path "$out_dir" --bin "$bin")
    slurm_write_job "$sub/scene.sbatch" "${common[@]}" --scene_index task
    slurm_write_job "$sub/aggregate.sbatch" "${common[@]}" --aggregate_only
    slurm_submit "$sub" watergs-reproduce "$pending" "$sub/scene.sbatch" "$sub/aggregate.sbatch"
    log "submitted array job $slurm_array_job (scenes $pending of ${#scenes[@]}) and aggregate job" \
      "$slurm_aggregate_job; logs in $sub"
    [ -n "$slurm_wait_for" ] || exit 0
    slurm_wait "$slurm_aggregate_job"
    [ "$out_dir/tables.md" -nt "$sub/scene.sbatch" ] ||
      die "aggregate job $slurm_aggregate_job wrote no new tables (log: $sub/aggregate-$slurm_aggregate_job.out)"
    log "tables: $out_dir/tables.md, $out_dir/claims.md, $out_dir/results.csv"
    exit 0
  fi
  log "every scene's steps are finished: nothing to submit; aggregating here"
fi

for entry in "${scenes[@]}"; do
  scene_steps "$entry"
done
[ -s "$manifest_file" ] || die "no finished run to make tables from"

log "aggregating into $out_dir/tables.md and $out_dir/results.csv"
settings="train_iterations=$train_iterations, embed_iterations=$embed_iterations, downscale=$downscale_option,"
settings+=" gamma=$gamma_option, seeds=$seeds_option, crop_size=$crop_size, num_threads=$num_threads"
python3 "$script_dir/aggregate_tables.py" --manifest "$manifest_file" --output_dir "$out_dir" \
  --main_length "$main_length" --settings "$settings" --note "$note"
python3 "$script_dir/check_claims.py" --results "$out_dir/results.csv" --output "$out_dir/claims.md" \
  --main_length "$main_length" "${baseline_args[@]}"
cp "$commands_file" "$out_dir/.commands.txt.tmp"
mv "$out_dir/.commands.txt.tmp" "$out_dir/commands.txt"
log "wrote $out_dir/tables.md, $out_dir/claims.md, $out_dir/results.csv and $out_dir/commands.txt"
