#!/usr/bin/env bash
# Times the everyday test tier (`ctest --test-dir BUILD -LE slow -j2`) and writes what the README's
# Testing section quotes: the command, commit (whether the tree was clean, whether a fresh clone),
# date, machine, load, wall time and CTest's summary lines. COLMAP's binary is replaced on PATH by
# one that records its call and fails, so a test of the tier that runs COLMAP fails and is named in
# the file ("colmap calls: ...").
#   scripts/time_fast_tier.sh [BUILD] [OUT_FILE]   (defaults: build, results/testing/fast_tier.txt)
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="${1:-$root/build}"
out="${2:-$root/results/testing/fast_tier.txt}"
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
mkdir -p "$tmp/bin" "$(dirname "$out")"
printf '#!/bin/sh\necho "colmap $*" >> "%s/colmap_calls"\nexit 1\n' "$tmp" > "$tmp/bin/colmap"
chmod +x "$tmp/bin/colmap"
# Whether the tested source is the commit named, read before the run (a test may write files): the
# record says "clean" or "dirty" either way, so no reader takes a missing remark for "clean".
# Untracked files count (a test may read them); the record being written does not, as it is not
# part of what was tested.
exclude=()
case "$out" in "$root"/*) exclude=(":(exclude)$out") ;; esac
changed=$(git -C "$root" status --porcelain --untracked-files=all -- . ${exclude[@]+"${exclude[@]}"} | wc -l)
if [ "$changed" -eq 0 ]; then tree=clean; else tree="dirty ($changed path(s) differ from HEAD)"; fi
# A fresh clone's HEAD reflog starts with "clone:" and holds nothing since but checkouts (of the
# commit to time); a commit, reset or pull after it means the checkout has a history of its own.
reflog=$(git -C "$root" reflog --format='%gs' HEAD 2>/dev/null || true)
if [ -z "$reflog" ]; then
  checkout="unknown whether a fresh clone (HEAD has no reflog)"
elif [ "$(tail -1 <<<"$reflog" | cut -c1-6)" = "clone:" ] &&
  ! sed '$d' <<<"$reflog" | grep -qv '^checkout:'; then
  checkout="a fresh clone ($(tail -1 <<<"$reflog"))"
else
  oldest=$(tail -1 <<<"$reflog" | cut -c1-60)
  checkout="not a fresh clone (HEAD's reflog: $(wc -l <<<"$reflog") entries, the oldest \"$oldest\")"
fi
build_source=$(sed -n 's/^CMAKE_HOME_DIRECTORY:INTERNAL=//p' "$build/CMakeCache.txt" 2>/dev/null || true)
[ "$build_source" = "$root" ] && build_source="this checkout"
command=(ctest --test-dir "$build" -LE slow -j2)
load_before=$(cut -d' ' -f1-3 /proc/loadavg)
start=$(date +%s%N)
set +e
PATH="$tmp/bin:$PATH" /usr/bin/time -f "%U %S" -o "$tmp/cpu" "${command[@]}" > "$tmp/ctest.log" 2>&1
rc=$?
set -e
wall=$(( ($(date +%s%N) - start) / 1000000000 ))
load_after=$(cut -d' ' -f1-3 /proc/loadavg)
{
  echo "# The everyday test tier, timed by scripts/time_fast_tier.sh"
  echo "command: ${command[*]/#$root\//} (colmap on PATH replaced by a stand-in that fails)"
  echo "commit: $(git -C "$root" rev-parse --short HEAD), working tree $tree"
  echo "checkout: $checkout; build configured from ${build_source:-an unknown source (no CMakeCache.txt)}"
  echo "date: $(date -u '+%Y-%m-%d %H:%M UTC')"
  echo "machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ *//')"
  echo "load average (1, 5, 15 min) before: $load_before; after: $load_after"
  echo "wall: $wall s"
  # CPU seconds of ctest and every test it ran: on 2 idle cores the tier needs at least half of it.
  read -r user sys < <(tail -1 "$tmp/cpu")
  echo "cpu (user + sys, all tests): $(python3 -c "print(round($user + $sys))") s"
  echo "exit status: $rc"
  echo "tests: $(ctest --test-dir "$build" -N -LE slow | grep -o 'Total Tests: [0-9]*' | grep -o '[0-9]*') in the tier, $(ctest --test-dir "$build" -N -L slow | grep -o 'Total Tests: [0-9]*' | grep -o '[0-9]*') labelled slow, $(ctest --test-dir "$build" -N | grep -o 'Total Tests: [0-9]*' | grep -o '[0-9]*') in all"
  echo "colmap calls: $( [ -s "$tmp/colmap_calls" ] && wc -l < "$tmp/colmap_calls" || echo 0)"
  echo
  echo "## CTest's summary"
  sed -n '/tests passed\|tests failed/,$p' "$tmp/ctest.log"
  echo
  echo "## The 15 longest tests (seconds)"
  grep -E 'Test +#[0-9]+:' "$tmp/ctest.log" |
    sed -E 's/.*Test +#[0-9]+: (.*[^ .]) \.+ *\**([A-Za-z][A-Za-z ]*[a-z]) +([0-9.]+) sec$/\3 \1 (\2)/' |
    sort -rn | sed -n 1,15p
} > "$out"
cat "$out"
exit $rc
