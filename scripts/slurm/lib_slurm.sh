# shellcheck shell=bash
# Slurm submission shared by scripts/slurm/watergs_batch.sh and datasets_scripts/reproduce_tables.sh
# --slurm (sourced, not run): resource options, one job array over the pending tasks, one aggregate job
# that runs after every array task ended (afterany: failed tasks do not block it), and waiting for it.
# The caller defines die.

slurm_cpus=4
slurm_mem=16G
slurm_time=12:00:00
slurm_partition=""
slurm_account=""
slurm_gpus=""
slurm_max_parallel=""
slurm_extra=""
slurm_aggregate_time=00:30:00
slurm_array_job="" slurm_aggregate_job=""  # set by slurm_submit

slurm_options_usage() {
  cat <<EOF
Slurm resources (each array task is one scene):
  --cpus_per_task N       CPU cores per scene, also watergs's --num_threads (default $slurm_cpus)
  --mem SIZE              memory per scene, sbatch syntax (default $slurm_mem)
  --time LIMIT            time limit per scene, sbatch syntax (default $slurm_time)
  --gpus N                GPUs per scene (--gres=gpu:N; default 1 with --device cuda, else none)
  --partition NAME        partition (default: the cluster's default)
  --account NAME          account to charge (default: yours)
  --max_parallel N        at most N scenes at once (--array=...%N; default no limit)
  --aggregate_time LIMIT  time limit of the aggregate job (default $slurm_aggregate_time; 1 core, 1G)
  --sbatch_args "ARGS"    further sbatch options for both jobs, word-split (e.g. "--qos=long --requeue")
EOF
}

# slurm_take_option OPTION VALUE: consumes a resource option (returns 0) or leaves it (returns 1).
slurm_take_option() {
  case "$1" in
    --cpus_per_task) slurm_cpus="$2" ;;
    --mem) slurm_mem="$2" ;;
    --time) slurm_time="$2" ;;
    --gpus) slurm_gpus="$2" ;;
    --partition) slurm_partition="$2" ;;
    --account) slurm_account="$2" ;;
    --max_parallel) slurm_max_parallel="$2" ;;
    --aggregate_time) slurm_aggregate_time="$2" ;;
    --sbatch_args) slurm_extra="$2" ;;
    *) return 1 ;;
  esac
}

# slurm_check_options DEVICE: dies on a malformed resource option; DEVICE cuda asks for a GPU by default.
slurm_check_options() {
  [[ "$slurm_cpus" =~ ^[1-9][0-9]*$ ]] || die "--cpus_per_task '$slurm_cpus' is not a whole number >= 1"
  [[ "$slurm_mem" =~ ^[1-9][0-9]*[KMGT]?$ ]] || die "--mem '$slurm_mem' is not a size such as 16G or 4000M"
  local time_re='^([0-9]+-)?[0-9]+(:[0-9]+){0,2}$'
  [[ "$slurm_time" =~ $time_re ]] || die "--time '$slurm_time' is not a Slurm time limit (e.g. 12:00:00 or 1-00:00:00)"
  [[ "$slurm_aggregate_time" =~ $time_re ]] || die "--aggregate_time '$slurm_aggregate_time' is not a Slurm time limit"
  [ -z "$slurm_max_parallel" ] || [[ "$slurm_max_parallel" =~ ^[1-9][0-9]*$ ]] ||
    die "--max_parallel '$slurm_max_parallel' is not a whole number >= 1"
  if [ -z "$slurm_gpus" ] && [ "$1" = cuda ]; then slurm_gpus=1; fi
  [ -z "$slurm_gpus" ] || [[ "$slurm_gpus" =~ ^[0-9]+$ ]] || die "--gpus '$slurm_gpus' is not a whole number"
}

# slurm_write_job FILE COMMAND...: a job script that runs COMMAND (each word shell-quoted).
slurm_write_job() {
  local file="$1"
  shift
  {
    echo "#!/usr/bin/env bash"
    echo "# Written by $(basename "$0") on $(date -u +%Y-%m-%dT%H:%M:%SZ); submitted with the sbatch options in submit.txt."
    printf 'exec'
    printf ' %q' "$@"
    echo
  } >"$file.tmp"
  chmod +x "$file.tmp"
  mv "$file.tmp" "$file"
}

# slurm_submit DIR NAME INDICES TASK_SCRIPT AGGREGATE_SCRIPT [--dry_run]: submits TASK_SCRIPT as an array
# over INDICES (e.g. 0,2,5), then AGGREGATE_SCRIPT after it; both logs go to DIR. Sets slurm_array_job and
# slurm_aggregate_job; the sbatch command lines are kept in DIR/submit.txt.
slurm_submit() {
  local dir="$1" name="$2" indices="$3" task="$4" aggregate="$5" dry="${6:-}"
  local common=() extra=()
  [ -n "$slurm_partition" ] && common+=(--partition="$slurm_partition")
  [ -n "$slurm_account" ] && common+=(--account="$slurm_account")
  read -r -a extra <<<"$slurm_extra"
  common+=("${extra[@]}")
  local array="$indices"
  [ -n "$slurm_max_parallel" ] && array+="%$slurm_max_parallel"
  local task_args=(--parsable --job-name="$name" --array="$array" --cpus-per-task="$slurm_cpus"
    --mem="$slurm_mem" --time="$slurm_time" --output="$dir/slurm-%A_%a.out" "${common[@]}")
  [ -n "$slurm_gpus" ] && [ "$slurm_gpus" != 0 ] && task_args+=(--gres="gpu:$slurm_gpus")
  local aggregate_args=(--parsable --job-name="$name-aggregate" --cpus-per-task=1 --mem=1G
    --time="$slurm_aggregate_time" --output="$dir/aggregate-%j.out" "${common[@]}")
  {
    printf 'sbatch'
    printf ' %q' "${task_args[@]}" "$task"
    printf '\nsbatch'
    printf ' %q' "${aggregate_args[@]}" --dependency=afterany:ARRAY_JOB "$aggregate"
    echo
  } >"$dir/submit.txt"
  if [ "$dry" = --dry_run ]; then
    slurm_array_job=DRY_RUN slurm_aggregate_job=DRY_RUN
    return
  fi
  command -v sbatch >/dev/null || die "sbatch not found: submit from a Slurm login node (or use --local)"
  slurm_array_job="$(sbatch "${task_args[@]}" "$task")" || die "sbatch refused the array job (command in $dir/submit.txt)"
  slurm_array_job="${slurm_array_job%%;*}"
  slurm_aggregate_job="$(sbatch "${aggregate_args[@]}" --dependency="afterany:$slurm_array_job" "$aggregate")" ||
    die "sbatch refused the aggregate job (array job $slurm_array_job was submitted; command in $dir/submit.txt)"
  slurm_aggregate_job="${slurm_aggregate_job%%;*}"
  echo "array job $slurm_array_job, aggregate job $slurm_aggregate_job" >>"$dir/submit.txt"
}

# slurm_wait JOB: returns once JOB has left the queue (polls squeue every few seconds).
slurm_wait() {
  local job="$1" out errors=0
  while :; do
    if out="$(squeue -h -j "$job" -o %T 2>&1)"; then
      errors=0
      [ -z "$out" ] && return 0
    elif [[ "$out" == *"Invalid job id"* ]]; then
      return 0  # purged from the controller's memory: it ended a while ago
    else
      errors=$((errors + 1))
      [ "$errors" -lt 10 ] || die "squeue keeps failing while waiting for job $job: $out"
    fi
    sleep "${SLURM_WAIT_POLL:-5}"
  done
}
