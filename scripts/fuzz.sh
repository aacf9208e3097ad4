#!/usr/bin/env bash
# Builds the libFuzzer targets (fuzz/*_fuzzer.cc) with clang, ASan and UBSan in
# build-fuzz/, generates their seed corpora and runs each target for a time
# budget, then prints executions, crashes, timeouts and OOMs per target.
#   bash scripts/fuzz.sh [seconds_per_target] [target...]   (default 60 s, all)
# Findings are written to build-fuzz/findings/<target>/; the log of each run
# is build-fuzz/logs/<target>.log. Exits 1 if any target found something.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-60}"
shift || true
dir=build-fuzz
jobs="${FUZZ_BUILD_JOBS:-2}"

cmake -S . -B "$dir" -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DWATERGS_FUZZ=ON -DWATERGS_BUILD_TESTS=OFF -DWATERGS_NATIVE_ARCH=OFF -DWATERGS_PYTHON=OFF >/dev/null
mapfile -t all < <(cd fuzz && ls ./*_fuzzer.cc | sed 's|^\./||; s|_fuzzer\.cc$||')
targets=("$@")
[ ${#targets[@]} -eq 0 ] && targets=("${all[@]}")
nice -n 10 cmake --build "$dir" -j"$jobs" --target watergs_fuzz_seeds "${targets[@]/%/_fuzzer}"

# Seeds are regenerated each time; the corpus folder keeps what earlier runs
# found, so longer campaigns build on shorter ones.
rm -rf "$dir/seeds"
"$dir/fuzz/watergs_fuzz_seeds" "$dir/seeds"
mkdir -p "$dir/logs"

# An input whose parse allocates > 1 GB or runs > 10 s is a finding: every
# reader must refuse absurd counts before allocating.
opts=(-rss_limit_mb=2048 -malloc_limit_mb=1024 -timeout=10 -print_final_stats=1
  -print_funcs=0)
# One thread: libFuzzer runs one input at a time, and OpenMP start-up costs
# more than it saves on fuzz-sized inputs.
export OMP_NUM_THREADS=1
export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1:allocator_may_return_null=0}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"

printf '%-14s %12s %10s %8s %9s %6s\n' target executions exec/s crashes timeouts ooms
status=0
for t in "${targets[@]}"; do
  corpus="$dir/corpus/$t"
  findings="$dir/findings/$t"
  mkdir -p "$corpus" "$findings"
  log="$dir/logs/$t.log"
  # -fork=1 keeps fuzzing after a finding (each one is saved and counted);
  # libFuzzer's own per-input limits still apply in the child.
  nice -n 10 "$dir/fuzz/${t}_fuzzer" "${opts[@]}" -fork=1 -ignore_crashes=1 \
    -ignore_timeouts=1 -ignore_ooms=1 -max_total_time="$seconds" \
    -artifact_prefix="$findings/" "$corpus" "$dir/seeds/$t" >"$log" 2>&1 || true
  # Fork mode's status lines ("#N: cov: ... exec/s R oom/timeout/crash: ...")
  # count executions over all jobs; the last one is the total.
  execs=$(grep -oE '^#[0-9]+' "$log" | tail -1 | tr -d '#')
  rate=$(( ${execs:-0} / seconds ))
  crashes=$(find "$findings" -name 'crash-*' | wc -l)
  timeouts=$(find "$findings" -name 'timeout-*' -o -name 'slow-unit-*' | wc -l)
  ooms=$(find "$findings" -name 'oom-*' -o -name 'leak-*' | wc -l)
  printf '%-14s %12s %10s %8s %9s %6s\n' "$t" "${execs:-0}" "${rate:-0}" \
    "$crashes" "$timeouts" "$ooms"
  [ "$crashes$timeouts$ooms" = "000" ] || status=1
done
exit $status
