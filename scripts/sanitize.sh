#!/usr/bin/env bash
# Builds watergs with sanitizers and runs tests under them; exits non-zero on
# any build failure, test failure or sanitizer report.
#   bash scripts/sanitize.sh address   # ASan + UBSan (GCC), the whole suite, in build-address/
#   bash scripts/sanitize.sh thread    # TSan (clang + libomp + Archer), the multithreaded
#                                      # rasterizer, projection, binning, loss, Adam, density
#                                      # and trainer tests, in build-thread/
# Extra arguments go to ctest (address) or to the gtest binary (thread), e.g.
#   bash scripts/sanitize.sh address -R Malformed
# Both build only the CLI and the test executables (no benchmarks). Run with `nice` on a
# shared machine: an ASan build of everything takes ~2x a normal one.
set -euo pipefail
cd "$(dirname "$0")/.."
kind="${1:-address}"
shift || true
jobs="${WATERGS_SANITIZE_JOBS:-2}"
# The CUDA backend is left out: its kernels need a GPU (scripts/gpu_check.sh runs
# compute-sanitizer there); the host code these sanitizers check is the same. So is the
# Python module: an instrumented extension does not load into an uninstrumented
# interpreter, and it runs the code the CLI tests run.
common=(-DCMAKE_BUILD_TYPE=RelWithDebInfo -DWATERGS_NATIVE_ARCH=OFF -DWATERGS_CUDA=OFF
  -DWATERGS_PYTHON=OFF)

case "$kind" in
  address)
    dir=build-address
    flags="-fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined"
    cmake -S . -B "$dir" "${common[@]}" \
      -DCMAKE_CXX_FLAGS="$flags" -DCMAKE_EXE_LINKER_FLAGS="$flags"
    targets=$(cmake --build "$dir" --target help | grep -o 'watergs_[a-z]*_test' | sort -u)
    # shellcheck disable=SC2086
    cmake --build "$dir" -j"$jobs" --target watergs $targets
    # abort_on_error: any report fails the test (the CLI children the tests spawn too).
    export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1
    export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
    ctest --test-dir "$dir" --output-on-failure --no-tests=error -j"$jobs" \
      -E clang_format_check "$@"
    ;;
  thread)
    # GCC's libgomp is not instrumented: TSan cannot see its barriers and reports every
    # parallel loop (and suppressing libgomp frames hides every worker thread). LLVM's
    # libomp with the Archer tool annotates OpenMP synchronisation for TSan, so this
    # build uses clang.
    dir=build-thread
    flags="-fsanitize=thread -fno-omit-frame-pointer -g"
    cmake -S . -B "$dir" "${common[@]}" -DCMAKE_CXX_COMPILER=clang++ \
      -DCMAKE_CXX_FLAGS="$flags" -DCMAKE_EXE_LINKER_FLAGS="$flags"
    cmake --build "$dir" -j"$jobs" --target watergs_gaussian_test
    llvm_lib="$(dirname "$(readlink -f "$(command -v clang++)")")/../lib"
    archer="$llvm_lib/libarcher.so"
    [ -f "$archer" ] || { echo "sanitize.sh: $archer not found (libomp-dev)" >&2; exit 1; }
    export OMP_TOOL_LIBRARIES="$archer"
    export ARCHER_OPTIONS="verbose=1"
    # libomp itself is not instrumented: its internal mutexes must not be judged
    # (Archer's recommended setting); user code and Archer's annotations still are.
    export TSAN_OPTIONS="halt_on_error=1 exitcode=66 history_size=4 ignore_noninstrumented_modules=1"
    # Two or more threads, whatever the machine, so that the parallel paths run.
    export OMP_NUM_THREADS="${OMP_NUM_THREADS:-4}"
    "$dir/tests/watergs_gaussian_test" \
      --gtest_filter='Rasterizer*:TileBinning*:Projection*:Loss*:Adam*:Trainer*:Density*' \
      "$@"
    ;;
  *) echo "usage: $0 address|thread [ctest or gtest arguments]" >&2; exit 2 ;;
esac
echo "sanitize.sh $kind: clean"
