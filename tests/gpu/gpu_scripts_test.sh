#!/usr/bin/env bash
# scripts/gpu_bundle.sh and scripts/gpu_check.sh without a GPU: the check
# script's argument handling (one-line errors, exit 2, before touching
# anything), and a bundle of a stand-in build (each binary a copy of
# /bin/true) that has the documented layout and that gpu_check.sh unpacks
# and runs: its parity stage runs each module's test binary and logs its
# exit status.
set -uo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd -P)"
check="$root/scripts/gpu_check.sh" bundle_sh="$root/scripts/gpu_bundle.sh"
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
fails=0
fail() { echo "FAIL: $*"; fails=$((fails + 1)); }
# expect_error CODE TEXT CMD...: CMD exits CODE with one stderr line holding TEXT.
expect_error() {
  local code=$1 text=$2; shift 2
  "$@" > "$tmp/stdout" 2> "$tmp/err"; local rc=$?
  [ $rc -eq "$code" ] || fail "$* exited $rc, not $code"
  [ "$(wc -l < "$tmp/err")" -eq 1 ] || fail "$*: not one error line: $(cat "$tmp/err")"
  grep -qF -- "$text" "$tmp/err" || fail "$*: error lacks '$text': $(cat "$tmp/err")"
}

bash -n "$check" || fail "gpu_check.sh syntax"
bash -n "$bundle_sh" || fail "gpu_bundle.sh syntax"

# Argument handling.
cd "$tmp"
: > fake.tar.xz
expect_error 2 "unknown argument 'paritty'" bash "$check" --bundle fake.tar.xz paritty
expect_error 2 "unknown argument '5'" bash "$check" --bundle fake.tar.xz 5
expect_error 2 "--deadline: expected seconds > 0, got 'abc'" bash "$check" --bundle fake.tar.xz --deadline abc
expect_error 2 "--out needs a value" bash "$check" --bundle fake.tar.xz --out
expect_error 2 "no bundle 'missing.tar.xz'" bash "$check" --bundle missing.tar.xz
parsed=$(GPU_CHECK_PARSE_ONLY=1 bash "$check" --bundle fake.tar.xz --deadline 60 sanitize parity)
[ "$parsed" = "stages: sanitize parity; bundle fake.tar.xz; out gpu_out; deadline 60" ] || fail "parsed: $parsed"
parsed=$(GPU_CHECK_PARSE_ONLY=1 bash "$check" --bundle fake.tar.xz demo profile)
[ "$parsed" = "stages: demo profile; bundle fake.tar.xz; out gpu_out; deadline 540" ] || fail "profile: $parsed"
parsed=$(GPU_CHECK_PARSE_ONLY=1 bash "$check" --bundle fake.tar.xz)
[ "$parsed" = "stages: parity demo bench sanitize; bundle fake.tar.xz; out gpu_out; deadline 540" ] || fail "default stages: $parsed"
parsed=$(GPU_CHECK_PARSE_ONLY=1 bash "$check" --bundle fake.tar.xz gsplat)
[ "$parsed" = "stages: gsplat; bundle fake.tar.xz; out gpu_out; deadline 540" ] || fail "gsplat: $parsed"
bash "$check" --help | grep -q "compute-sanitizer" || fail "gpu_check.sh --help"
gsplat_sh="$root/scripts/gsplat_bundle.sh"
bash -n "$gsplat_sh" || fail "gsplat_bundle.sh syntax"
expect_error 2 "--source: a gsplat git checkout" bash "$gsplat_sh"
expect_error 2 "unknown argument '--frobnicate'" bash "$gsplat_sh" --frobnicate
expect_error 2 "no revision" bash "$gsplat_sh" --source "$tmp"
expect_error 2 "unknown argument '--frobnicate'" bash "$bundle_sh" --frobnicate
(cd "$root" && expect_error 2 "no build folder" bash "$bundle_sh" --build "$tmp/none")

# A stand-in build, bundled from the project's root.
b="$tmp/build"
mkdir -p "$b/plugin" "$b/tests" "$b/benchmarks"
cp /bin/true "$b/plugin/watergs"
for m in gaussian distortion watermark plugin; do cp /bin/true "$b/tests/watergs_${m}_test"; done
cp /bin/true "$b/benchmarks/decoder_benchmark"
cp /bin/true "$b/benchmarks/raster_benchmark"
(cd "$root" && GPU_BUNDLE_XZ_LEVEL=0 bash "$bundle_sh" --build "$b" --out "$tmp/out") > "$tmp/bundle.log" 2>&1 ||
  fail "gpu_bundle.sh: $(cat "$tmp/bundle.log")"
tar -tJf "$tmp/out/bundle.tar.xz" > "$tmp/list" || fail "bundle does not unpack"
for entry in paths repo/CMakeLists.txt repo/scripts/gpu_check.sh repo/watermark/models/decoder_48.bin \
    build/plugin/watergs build/tests/watergs_gaussian_test build/tests/watergs_plugin_test \
    build/benchmarks/decoder_benchmark; do
  grep -qx "$entry" "$tmp/list" || fail "bundle lacks $entry"
done
grep -q "^repo/docs/" "$tmp/list" && fail "bundle holds docs/"
grep -q "^libs/" "$tmp/list" || fail "bundle has no libs/"
if ls /lib/x86_64-linux-gnu/libgdal.so.* > /dev/null 2>&1; then
  grep -q "^libs/libgdal\.so\.[0-9]*$" "$tmp/list" || fail "no GDAL stub in libs/"
fi
tar -xJf "$tmp/out/bundle.tar.xz" -C "$tmp" paths
[ "$(sed -n 1p "$tmp/paths")" = "$root" ] || fail "paths line 1: $(sed -n 1p "$tmp/paths")"
[ "$(sed -n 2p "$tmp/paths")" = "$b" ] || fail "paths line 2: $(sed -n 2p "$tmp/paths")"

# gpu_check.sh from the project's root (the sources are already in place):
# the parity stage runs the stand-in test binaries.
rm -rf "$b"
(cd "$root" && bash "$check" --bundle "$tmp/out/bundle.tar.xz" --out "$tmp/log" parity) > "$tmp/check.log" 2>&1 ||
  fail "gpu_check.sh parity: $(cat "$tmp/check.log")"
[ -x "$b/tests/watergs_gaussian_test" ] || fail "gpu_check.sh did not place the build at $b"
for m in gaussian distortion watermark plugin; do
  grep -q "^== $m parity: exit 0" "$tmp/log/parity.txt" || fail "no $m parity run: $(cat "$tmp/log/parity.txt")"
done
[ -f "$tmp/log/env.txt" ] || fail "no env.txt"

# The gsplat stage runs watergs' raster benchmark, then gsplat's timing only
# where PyTorch with CUDA is there; elsewhere it says so and does not fail.
: > "$tmp/gsplat.tar.xz"
if ! python3 -c 'import sys, torch; sys.exit(0 if torch.cuda.is_available() else 1)' 2> /dev/null; then
  (cd "$root" && bash "$check" --bundle "$tmp/out/bundle.tar.xz" --gsplat "$tmp/gsplat.tar.xz" \
    --out "$tmp/log" gsplat) > "$tmp/gsplat.log" 2>&1 || fail "gpu_check.sh gsplat: $(cat "$tmp/gsplat.log")"
  grep -q "^== raster_benchmark 1M (watergs; writes the scene): exit 0" "$tmp/log/gsplat.txt" ||
    fail "gsplat stage: no raster_benchmark run: $(cat "$tmp/log/gsplat.txt")"
  grep -q "no PyTorch with CUDA on this machine" "$tmp/log/gsplat.txt" ||
    fail "gsplat stage: no line about PyTorch: $(cat "$tmp/log/gsplat.txt")"
fi

[ $fails -eq 0 ] && echo "gpu scripts: all checks passed"
exit $((fails > 0))
