# Shared by the baseline_*_3dgs.sh scripts (sourced, not run).

# baseline_run OUT COMMAND...: appends COMMAND (shell-quoted, so it can be
# pasted back) to OUT/commands.txt, then runs it.
baseline_run() {
  local out="$1"
  shift
  printf '%q ' "$@" >> "$out/commands.txt"
  echo >> "$out/commands.txt"
  "$@"
}
