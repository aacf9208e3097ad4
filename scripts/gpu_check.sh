#!/usr/bin/env bash
# One-call GPU verification of the CUDA backend (issue 8), for the device
# machine: builds with CUDA for the local GPU, runs the CUDA parity tests
# (they skip without a GPU) and the benchmarks on cuda and cpu, and writes
# logs to OUT (default $OUT, else ./gpu_check). Exit status: the tests'.
#   bash scripts/gpu_check.sh [OUT]
set -uo pipefail
cd "$(dirname "$0")/.."
out="${1:-${OUT:-gpu_check}}"
mkdir -p "$out"
build=build-gpu
nvidia-smi > "$out/nvidia_smi.txt" 2>&1
arch=$(nvidia-smi --query-gpu=compute_cap --format=csv,noheader 2>/dev/null | head -1 | tr -d '.')
cmake -S . -B "$build" -DWATERGS_CUDA=ON -DCMAKE_CUDA_ARCHITECTURES="${arch:-90}" \
  > "$out/configure.txt" 2>&1 || { tail -20 "$out/configure.txt"; exit 1; }
cmake --build "$build" -j"$(nproc)" > "$out/build.txt" 2>&1 || { grep -m20 -E "error" "$out/build.txt"; exit 1; }
status=0
for module in gaussian distortion watermark plugin; do
  "$build/tests/watergs_${module}_test" --gtest_filter='*Cuda*:*CUDA*' \
    >> "$out/parity_tests.txt" 2>&1 || status=1
done
grep -E "^\[  (PASSED|FAILED|SKIPPED) |^\[  FAILED  \]" "$out/parity_tests.txt" | tail -40
# Memory errors, shared-memory races and sync errors in the kernels that the
# parity tests exercise hardest (multi-batch tiles, crops, empty models).
if command -v compute-sanitizer >/dev/null 2>&1; then
  for tool in memcheck racecheck synccheck; do
    compute-sanitizer --tool "$tool" --error-exitcode 9 \
      "$build/tests/watergs_gaussian_test" --gtest_filter='CudaRasterizer.DeepTileStackMatchesCpu:CudaRasterizer.CropRectsMatchCpu:CudaRasterizer.EmptyModelRendersBackground:CudaRasterizer.ShDegreeZeroModelMatchesCpu' \
      > "$out/sanitizer_$tool.txt" 2>&1 || { status=1; echo "compute-sanitizer $tool: errors (see sanitizer_$tool.txt)"; }
  done
fi
demo=datasets_scripts/demo_scene
{
  "$build/benchmarks/raster_benchmark" --device cuda --threads "$(nproc)"
  "$build/benchmarks/raster_benchmark" --device cuda --scenes 1000 --repeats 9
  "$build/benchmarks/raster_benchmark" --device cpu --threads "$(nproc)" --scenes 100
  "$build/benchmarks/train_benchmark" --device cuda --json "$out/train_cuda.json"
  "$build/benchmarks/train_benchmark" --device cpu --json "$out/train_cpu.json"
  "$build/benchmarks/decoder_benchmark" --device cuda 5
} > "$out/benchmarks.txt" 2>&1
tail -40 "$out/benchmarks.txt"
exit $status
