#!/usr/bin/env bash
# Watermarks many scenes at once: one Slurm job array over the scenes of a manifest (per scene: train or
# take a PLY, embed the owner's message, evaluate under the attacks; scripts/slurm/run_scene.sh), then a
# dependent job that aggregates every scene into OUT/summary.{csv,json,md}. Resubmitting the same command
# skips the scenes already done, so a preempted or failed array resumes. See docs/batch.md.
set -euo pipefail
script_name="$(basename "$0")"
script_dir="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
repo_root="$(cd "$script_dir/../.." && pwd)"
# shellcheck source=lib_slurm.sh
source "$script_dir/lib_slurm.sh"

usage() {
  cat <<EOF
Usage: bash scripts/slurm/$script_name --manifest FILE --output_path OUT [options]

The manifest has one scene per line, '#' starts a comment:
  WORKSPACE [key=value ...]      (shell quoting: message="text:ACME 01"; relative paths are
                                  relative to the manifest's folder)
  keys: name (default: the workspace folder's name), ply (an existing raw model: no training),
        downscale, train_iterations, embed_iterations, message, decoder, seed, attacks,
        train_args, embed_args, eval_args (further watergs options, word-split)
A key on a line wins over the option of the same name below.

Scene defaults:
  --message M             the owner's message (watergs's text:... or bits:...); required unless every line has one
  --decoder PATH          decoder weights (default watermark/models/decoder_48.bin)
  --downscale D, --train_iterations N, --embed_iterations N, --seed S
                          (default: watergs's own defaults; seed 0)
  --attacks LIST          model attacks of the evaluation (default identity,gn:0.01,dropout:0.1,crop:0.1)
  --train_args, --embed_args, --eval_args "ARGS"
                          further options of watergs train / embed / eval

Run:
  --device cpu|cuda|auto  watergs's --device (cuda asks Slurm for a GPU per scene; auto takes one if --gpus asks; default cpu)
  --bin PATH              watergs binary, visible from the compute nodes (default build/plugin/watergs)
  --checkpoint_every N    training and embedding checkpoints every N iterations (default 1000): a
                          signalled (preempted, timed-out, scancelled) step resumes from its last one
  --retry_failed          run failed scenes again (by default a scene that failed stays failed: its
                          error is most often its input; interrupted scenes always resume)
  --wait                  wait for the aggregate job, print the table; exit 1 if a scene is not done
  --local                 no Slurm: run the pending scenes here, one after the other, then aggregate
  --prepare               only write OUT/scenes.tsv (for Kubernetes, scripts/k8s/) and list what would run
  --dry_run               write the job scripts and OUT/submissions/*/submit.txt, submit nothing
  -h, --help              this text

$(slurm_options_usage)

Outputs: OUT/scenes/NAME/ (train/, watermarked.ply, eval.json, *.log, *.seconds, status.json),
OUT/summary.csv, .json, .md, and OUT/submissions/TIME/ (scene table, job scripts, Slurm logs).
EOF
}

die() {
  echo "$script_name: error: $*" >&2
  exit 1
}
log() { echo "[$(date -u +%H:%M:%S)] $*"; }

manifest="" out="" device=cpu retry="" wait="" mode=slurm checkpoint_every=1000
bin="${WATERGS_BIN:-$repo_root/build/plugin/watergs}"
python="${WATERGS_PYTHON:-python3}"
sets=(--set "decoder=$repo_root/watermark/models/decoder_48.bin")
while [ $# -gt 0 ]; do
  case "$1" in
    -h | --help) usage; exit 0 ;;
    --retry_failed) retry=--retry_failed; shift; continue ;;
    --wait) wait=1; shift; continue ;;
    --local) mode=local; shift; continue ;;
    --prepare) mode=prepare; shift; continue ;;
    --dry_run) mode=dry_run; shift; continue ;;
  esac
  [ $# -ge 2 ] || die "option $1 needs a value (see --help)"
  case "$1" in
    --manifest) manifest="$2" ;;
    --output_path) out="$2" ;;
    --device) device="$2" ;;
    --bin) bin="$2" ;;
    --checkpoint_every) checkpoint_every="$2" ;;
    --message | --decoder | --downscale | --train_iterations | --embed_iterations | --seed | --attacks | \
      --train_args | --embed_args | --eval_args) sets+=(--set "${1#--}=$2") ;;
    *) slurm_take_option "$1" "$2" || die "unknown option '$1' (see --help)" ;;
  esac
  shift 2
done
[ -n "$manifest" ] || die "--manifest is required (see --help)"
[ -n "$out" ] || die "--output_path is required (see --help)"
[[ "$device" =~ ^(cpu|cuda|auto)$ ]] || die "--device '$device' is not cpu, cuda or auto"
[[ "$checkpoint_every" =~ ^[0-9]+$ ]] || die "--checkpoint_every '$checkpoint_every' is not a number of iterations"
slurm_check_options "$device"
command -v "$python" >/dev/null || die "$python not found (python3 runs the bookkeeping)"
[ "$mode" = prepare ] || [ "$mode" = dry_run ] || [ -x "$bin" ] ||
  die "watergs binary '$bin' not found or not executable (build it, or pass --bin)"
# Array tasks may start in another folder (--sbatch_args --chdir=...): the binary by its absolute path.
[ ! -e "$bin" ] || bin="$(realpath "$bin")"
tool() { "$python" "$script_dir/batch_tool.py" "$@"; }

mkdir -p "$out"
out="$(cd "$out" && pwd)"
# Each submission reads its own copy of the scene table: a later submission with another manifest cannot
# shift the indices of tasks still queued.
sub="$out/submissions/$(date -u +%Y%m%dT%H%M%SZ)-$$"
[ "$mode" = prepare ] || mkdir -p "$sub"
if [ "$mode" = prepare ]; then
  num_scenes="$(tool manifest --manifest "$manifest" --output "$out/scenes.tsv" "${sets[@]}")" || exit 1
  tool pending --scenes "$out/scenes.tsv" --output_path "$out" $retry >/dev/null
  log "wrote $out/scenes.tsv: $num_scenes scenes (Kubernetes: completions: $num_scenes, docs/batch.md)"
  exit 0
fi
# On a bad manifest the tool's one-line error (file:line: problem) is the message; nothing is submitted.
num_scenes="$(tool manifest --manifest "$manifest" --output "$sub/scenes.tsv" --output "$out/scenes.tsv" \
  "${sets[@]}")" || { rmdir "$sub" 2>/dev/null; exit 1; }
pending="$(tool pending --scenes "$sub/scenes.tsv" --output_path "$out" $retry)"
num_pending=0
[ -z "$pending" ] || num_pending=$(($(tr -cd , <<<"$pending" | wc -c) + 1))
log "$num_scenes scenes in $manifest, $num_pending to run${pending:+ (indices $pending)}"

task=(bash "$script_dir/run_scene.sh" --scenes "$sub/scenes.tsv" --output_path "$out" --device "$device"
  --bin "$bin" --checkpoint_every "$checkpoint_every")
aggregate=("$python" "$script_dir/batch_tool.py" aggregate --scenes "$sub/scenes.tsv" --output_path "$out")

finish() {  # prints the table; with --wait, exit 1 unless every scene is done
  [ -f "$out/summary.md" ] || die "no $out/summary.md (see the aggregate job's log in $sub)"
  cat "$out/summary.md"
  grep -q '"problems": 0,' "$out/summary.json" || exit 1
}

case "$mode" in
  local)
    # One scene after another; a failed scene is in the table that finish prints.
    IFS=, read -r -a indices <<<"$pending"
    for i in "${indices[@]+"${indices[@]}"}"; do
      "${task[@]}" --index "$i" --num_threads "${SLURM_CPUS_PER_TASK:-0}" || true
    done
    "${aggregate[@]}" >/dev/null
    finish ;;
  slurm | dry_run)
    if [ "$num_pending" -eq 0 ]; then
      log "nothing to submit; aggregating here"
      "${aggregate[@]}" >/dev/null
      [ -z "$wait" ] || finish
      exit 0
    fi
    slurm_write_job "$sub/scene.sbatch" "${task[@]}"
    slurm_write_job "$sub/aggregate.sbatch" "${aggregate[@]}"
    slurm_submit "$sub" watergs-batch "$pending" "$sub/scene.sbatch" "$sub/aggregate.sbatch" \
      "$([ "$mode" = dry_run ] && echo --dry_run)"
    if [ "$mode" = dry_run ]; then
      log "dry run: job scripts in $sub, sbatch commands:"
      cat "$sub/submit.txt"
      exit 0
    fi
    log "submitted array job $slurm_array_job ($num_pending scenes) and aggregate job $slurm_aggregate_job;" \
      "logs in $sub"
    if [ -n "$wait" ]; then
      slurm_wait "$slurm_aggregate_job"
      # The aggregate job rewrites the summary; one older than this submission means it did not run.
      [ "$out/summary.json" -nt "$sub/scenes.tsv" ] ||
        die "aggregate job $slurm_aggregate_job wrote no new summary (log: $sub/aggregate-$slurm_aggregate_job.out)"
      finish
    fi ;;
esac
