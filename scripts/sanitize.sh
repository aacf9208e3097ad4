#!/usr/bin/env bash
# Builds watergs with sanitizers and runs the test suite under them.
#   bash scripts/sanitize.sh address   # AddressSanitizer + UndefinedBehaviorSanitizer, whole suite
#   bash scripts/sanitize.sh thread    # ThreadSanitizer, the multithreaded rasterizer tests
set -euo pipefail
cd "$(dirname "$0")/.."
kind="${1:-address}"
case "$kind" in
  address)
    flags="-fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined"
    filter="" ;;
  thread)
    # OpenMP's runtime is not TSan-instrumented; libgomp reports false races on its own
    # barriers, so suppress inside libgomp only.
    flags="-fsanitize=thread -fno-omit-frame-pointer"
    filter="-R (Raster|Rasterizer|TileBinning|Projection)" ;;
  *) echo "usage: $0 address|thread" >&2; exit 2 ;;
esac
dir="build-$kind"
cmake -S . -B "$dir" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DWATERGS_NATIVE_ARCH=OFF \
  -DCMAKE_CXX_FLAGS="$flags" -DCMAKE_EXE_LINKER_FLAGS="$flags"
cmake --build "$dir" -j2
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
export TSAN_OPTIONS="halt_on_error=1 suppressions=$PWD/scripts/tsan.supp"
# shellcheck disable=SC2086
ctest --test-dir "$dir" --output-on-failure -j2 -E clang_format_check $filter
