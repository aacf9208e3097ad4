#!/usr/bin/env bash
# One scene of a watergs batch: train (or take the given PLY), embed the owner's message, evaluate under
# the attacks. Run as a Slurm array task by watergs_batch.sh, as a pod of the Kubernetes Indexed Job in
# scripts/k8s/, or by hand. Each step is cached (a rerun resumes after the last finished step), the scene
# holds a lock while it runs, and OUT/scenes/NAME/status.json (written atomically) ends as done, failed
# (with the failing step's one-line error) or interrupted (a signal: time limit, preemption, scancel).
#   run_scene.sh --scenes TABLE --output_path OUT [--index K] [--device cpu|cuda|auto] [--num_threads N] [--bin PATH]
#                [--checkpoint_every N]   (training and embedding checkpoints, default 1000 iterations: a
#                                          preempted step resumes from its last one)
# K defaults to $SLURM_ARRAY_TASK_ID, then $JOB_COMPLETION_INDEX (Kubernetes); N to $SLURM_CPUS_PER_TASK
# (0 = all cores). Exit status: 0 done (or already done, or being run by another task), 3 failed (its
# input, most often: running it again gives the same error), 1 interrupted (worth running again), 2 bad
# usage. Kubernetes tells 3 from 1 to retry only the interrupted scenes (scripts/k8s/).
set -euo pipefail
script_dir="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
repo_root="$(cd "$script_dir/../.." && pwd)"
# shellcheck source=../../datasets_scripts/lib_steps.sh
source "$repo_root/datasets_scripts/lib_steps.sh"

readonly EXIT_FAILED=3 EXIT_INTERRUPTED=1

usage_error() {
  echo "run_scene.sh: error: $*" >&2
  exit 2
}

scenes="" out="" device=cpu
index="${SLURM_ARRAY_TASK_ID:-${JOB_COMPLETION_INDEX:-}}"
num_threads="${SLURM_CPUS_PER_TASK:-0}"
bin="${WATERGS_BIN:-$repo_root/build/plugin/watergs}"
python="${WATERGS_PYTHON:-python3}"
checkpoint_every=1000
while [ $# -gt 0 ]; do
  [ $# -ge 2 ] || usage_error "option $1 needs a value"
  case "$1" in
    --scenes) scenes="$2" ;;
    --output_path) out="$2" ;;
    --index) index="$2" ;;
    --device) device="$2" ;;
    --num_threads) num_threads="$2" ;;
    --bin) bin="$2" ;;
    --checkpoint_every) checkpoint_every="$2" ;;
    *) usage_error "unknown option '$1'" ;;
  esac
  shift 2
done
[ -n "$scenes" ] && [ -n "$out" ] || usage_error "--scenes and --output_path are required"
[ -n "$index" ] || usage_error "no scene index (--index, SLURM_ARRAY_TASK_ID or JOB_COMPLETION_INDEX)"

tool() { "$python" "$script_dir/batch_tool.py" "$@"; }
readarray -d '' -t f < <(tool row --scenes "$scenes" --index "$index")
[ "${#f[@]}" -ge 17 ] || usage_error "$scenes: cannot read scene $index"
name="${f[0]}" workspace="${f[1]}" ply="${f[2]}" downscale="${f[3]}" train_iterations="${f[4]}"
embed_iterations="${f[5]}" message="${f[6]}" decoder="${f[7]}" seed="${f[8]:-0}" attacks="${f[9]}"
fingerprint="${f[13]}"
k=14
n="${f[k]}" train_args=("${f[@]:k+1:n}") k=$((k + 1 + n))
n="${f[k]}" embed_args=("${f[@]:k+1:n}") k=$((k + 1 + n))
n="${f[k]}" eval_args=("${f[@]:k+1:n}")

dir="$out/scenes/$name"
mkdir -p "$dir"
status_file="$dir/status.json"
exec 9>"$dir/.lock"
if ! flock -n 9; then
  step_log "scene $name: another task holds $dir/.lock (running it now); leaving it to that task"
  exit 0
fi
if grep -q '"state": "done"' "$status_file" 2>/dev/null && grep -q "\"fingerprint\": \"$fingerprint\"" "$status_file"; then
  step_log "scene $name: already done ($status_file)"
  exit 0
fi

# The step caches below were made with the options of the fingerprint in status.json: a scene started
# with other options (message, iterations, ...) would end "done" from stale steps, so it is refused.
previous=$(grep -o '"fingerprint": "[^"]*"' "$status_file" 2>/dev/null | head -1 | cut -d'"' -f4 || true)
if [ -n "$previous" ] && [ "$previous" != "$fingerprint" ]; then
  error="$dir holds steps made with other manifest options; give the scene another name= or delete the folder"
  step_log "error: scene $name: $error"
  # A done scene keeps its status (its outputs are valid for the options it was made with).
  grep -q '"state": "done"' "$status_file" && exit "$EXIT_FAILED"
  tool status --file "$status_file" --scene "$name" --state failed --step start --error "$error" \
    --fingerprint "$previous"
  exit "$EXIT_FAILED"
fi

current_step=start
set_status() {  # STATE [ERROR]
  tool status --file "$status_file" --scene "$name" --state "$1" --step "$current_step" \
    --error "${2:-}" --fingerprint "$fingerprint"
}
on_signal() {
  trap - TERM INT HUP
  set_status interrupted "terminated by SIG$1 (time limit, preemption or cancel); resubmit to resume"
  step_log "scene $name: interrupted by SIG$1 during $current_step"
  exit "$EXIT_INTERRUPTED"
}
for sig in TERM INT HUP; do
  # shellcheck disable=SC2064
  trap "on_signal $sig" "$sig"
done
set_status running

# step NAME COMMAND...: a cached step of this scene; on failure records the step's one-line error.
step() {
  local what="$1"
  shift
  current_step="$what"
  local rc=0
  step_run "$dir/$what.seconds" "$dir/$what.log" "$what $name" "$@" || rc=$?
  [ "$rc" -eq 0 ] && return 0
  step_log "scene $name: $what failed: $STEP_ERROR (log: $dir/$what.log)"
  if [ "$rc" -gt 128 ]; then
    # Killed by a signal the script itself did not get (the OOM killer's SIGKILL): worth a resubmission.
    set_status interrupted "$what killed by signal $((rc - 128)) (out of memory?): $STEP_ERROR"
    exit "$EXIT_INTERRUPTED"
  fi
  set_status failed "$STEP_ERROR"
  exit "$EXIT_FAILED"
}

step_log "scene $name ($workspace) on $(hostname), $num_threads threads, device $device"
current_step=check
if [ ! -x "$bin" ]; then
  set_status failed "watergs binary '$bin' not found or not executable (build it, or pass --bin)"
  exit "$EXIT_FAILED"
fi
common=(--num_threads "$num_threads" --device "$device")
[ -n "$downscale" ] && common+=(--downscale "$downscale")
raw="$ply"
if [ -z "$ply" ]; then
  iters=(--checkpoint_every "$checkpoint_every")
  [ -n "$train_iterations" ] && iters+=(--iterations "$train_iterations")
  # An interrupted training resumes from its last checkpoint, or starts over without one.
  if [ -f "$dir/train/checkpoint.ckpt" ]; then
    iters+=(--resume)
  elif [ -d "$dir/train" ]; then
    iters+=(--overwrite)
  fi
  step train "$bin" train --workspace_path "$workspace" --output_path "$dir/train" --seed "$seed" --split train \
    "${iters[@]}" "${common[@]}" "${train_args[@]}"
  raw="$dir/train/point_cloud.ply"
fi
iters=(--checkpoint_every "$checkpoint_every")
[ -n "$embed_iterations" ] && iters+=(--iterations "$embed_iterations")
[ -f "$dir/watermarked.ply.ckpt" ] && iters+=(--resume)
# The blind reading, as eval's summary columns (and the paper's tables) read it; --embed_args
# "--reading owner" embeds for the owner's reading instead.
step embed "$bin" embed --input_path "$raw" --workspace_path "$workspace" --decoder "$decoder" \
  --message "$message" --output_path "$dir/watermarked.ply" --seed "$seed" --split train --reading blind "${iters[@]}" \
  "${common[@]}" "${embed_args[@]}"
rm -f "$dir/watermarked.ply.ckpt"  # the finished embedding's state (three times the PLY): done with it
step eval "$bin" eval --raw_path "$raw" --input_path "$dir/watermarked.ply" --workspace_path "$workspace" \
  --decoder "$decoder" --message "$message" --attacks "$attacks" --image_attacks '' --seed "$seed" \
  --output_path "$dir/eval" "${common[@]}" "${eval_args[@]}"
current_step=""
set_status "done"
step_log "scene $name: done ($dir)"
