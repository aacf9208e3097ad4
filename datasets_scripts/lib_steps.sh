# shellcheck shell=bash
# Cached, timed pipeline steps shared by datasets_scripts/reproduce_tables.sh and
# scripts/slurm/run_scene.sh (sourced, not run): a step runs once, and a rerun of
# an interrupted pipeline skips the steps that finished.

step_log() { echo "[$(date -u +%H:%M:%S)] $*"; }

# step_run DONE LOG WHAT COMMAND...: runs COMMAND (niced, stdout and stderr to
# LOG) unless DONE exists; on success writes its wall time in seconds to DONE,
# atomically, so DONE exists only for a step that finished. On failure prints
# LOG's last lines to stderr, sets STEP_ERROR to the last line of LOG (watergs
# ends with its one-line error) and returns COMMAND's exit status.
step_run() {
  local done_file="$1" log_file="$2" what="$3"
  shift 3
  STEP_ERROR=""
  if [ -f "$done_file" ]; then
    step_log "cached: $what ($(cat "$done_file") s)"
    return 0
  fi
  step_log "running: $what"
  local start end status=0
  start=$(date +%s%N)
  nice -n 10 "$@" >"$log_file" 2>&1 || status=$?
  if [ "$status" -ne 0 ]; then
    tail -n 5 "$log_file" >&2
    # Progress bars redraw with carriage returns: the last line is what follows the last one.
    STEP_ERROR="$(tr '\r' '\n' <"$log_file" | grep -v '^[[:space:]]*$' | tail -n 1 | cut -c 1-400)"
    [ -n "$STEP_ERROR" ] || STEP_ERROR="exit status $status without output"
    return "$status"
  fi
  end=$(date +%s%N)
  awk -v ns=$((end - start)) 'BEGIN { printf "%.3f\n", ns / 1e9 }' >"$done_file.tmp"
  mv "$done_file.tmp" "$done_file"
  step_log "done: $what in $(cat "$done_file") s"
}
