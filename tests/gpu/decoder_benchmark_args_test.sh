#!/usr/bin/env bash
# decoder_benchmark's command line: every malformed word is a one-line
# error with exit status 2 (scripts once passed "--device cuda 5", which it
# read as a weights file named 5), and --device cuda on the shipped
# random-feature decoder runs: without a GPU it says why on one line and
# gives the CPU figures.
#   decoder_benchmark_args_test.sh PATH/TO/decoder_benchmark
set -uo pipefail
bench="$1"
root="$(cd "$(dirname "$0")/../.." && pwd -P)"
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
fails=0
fail() { echo "FAIL: $*"; fails=$((fails + 1)); }
expect_error() {
  local text=$1; shift
  "$bench" "$@" > "$tmp/stdout" 2> "$tmp/stderr"; local rc=$?
  [ $rc -eq 2 ] || fail "$* exited $rc, not 2"
  [ "$(wc -l < "$tmp/stderr")" -eq 1 ] || fail "$*: not one error line: $(cat "$tmp/stderr")"
  grep -qF -- "$text" "$tmp/stderr" || fail "$*: error lacks '$text': $(cat "$tmp/stderr")"
  [ -s "$tmp/stdout" ] && fail "$*: timed something before failing"
}
expect_error "'5' is not a weights file (the repeat count is --repeats N)" --device cuda 5
expect_error "--device: expected cpu, cuda or auto, got 'gpu'" --device gpu
expect_error "--device needs a value" --device
expect_error "--repeats: expected a whole number >= 1, got '0'" --repeats 0
expect_error "--repeats: expected a whole number >= 1, got '3x'" --repeats=3x
expect_error "unknown option '--repeat'" --repeat 3
expect_error "README.md: not a watergs network file" "$root/README.md"
# A weights file the benchmark cannot time: one line naming it.
printf 'not a network' > "$tmp/bad.bin"
expect_error "$tmp/bad.bin" "$tmp/bad.bin"

"$bench" --device cuda --repeats 1 "$root/watermark/models/decoder_48.bin" > "$tmp/stdout" 2> "$tmp/stderr" ||
  fail "--device cuda on the shipped decoder: exit $? $(cat "$tmp/stderr")"
grep -q "feature-decoder, 48 bits" "$tmp/stdout" || fail "no feature decoder header: $(cat "$tmp/stdout")"
grep -q "1280x800: Logits" "$tmp/stdout" || fail "no full-frame timing: $(cat "$tmp/stdout")"
if grep -q "no GPU" "$tmp/stdout"; then
  [ "$(grep -c "no GPU" "$tmp/stdout")" -eq 1 ] || fail "the fallback is said more than once"
  grep -q "^decoder_benchmark --device cuda: no GPU (.*): CPU timings$" "$tmp/stdout" || fail "fallback line: $(head -1 "$tmp/stdout")"
fi
[ $fails -eq 0 ] && echo "decoder_benchmark arguments: all checks passed"
exit $((fails > 0))
