#!/usr/bin/env bash
# GPU verification of the CUDA backend (issue 8), for the device machine:
# builds with CUDA for the local GPU, runs the CUDA parity tests (they skip
# without a GPU), compute-sanitizer on the rasterizer's hardest tests, and the
# benchmarks on cuda and cpu; logs go to OUT (default $OUT, else ./gpu_check).
# A device call is limited to 10 minutes and the build stays on a warm
# machine, so the stages can run in separate calls:
#   bash scripts/gpu_check.sh [OUT] [build] [tests] [sanitize] [bench]
# (no stage named: all four). Exit status: non-zero if a stage failed.
set -uo pipefail
cd "$(dirname "$0")/.."
out="${1:-${OUT:-gpu_check}}"
shift || true
stages="${*:-build tests sanitize bench}"
mkdir -p "$out"
build=build-gpu
status=0

stage_build() {
  nvidia-smi > "$out/nvidia_smi.txt" 2>&1
  local arch
  arch=$(nvidia-smi --query-gpu=compute_cap --format=csv,noheader 2>/dev/null | head -1 | tr -d '.')
  cmake -S . -B "$build" -DWATERGS_CUDA=ON -DCMAKE_CUDA_ARCHITECTURES="${arch:-90}" \
    > "$out/configure.txt" 2>&1 || { tail -20 "$out/configure.txt"; return 1; }
  cmake --build "$build" -j"$(nproc)" > "$out/build.txt" 2>&1 ||
    { grep -m20 -E "error" "$out/build.txt"; return 1; }
}

stage_tests() {
  local rc=0 module
  : > "$out/parity_tests.txt"
  for module in gaussian distortion watermark plugin; do
    "$build/tests/watergs_${module}_test" --gtest_filter='*Cuda*:*CUDA*' \
      >> "$out/parity_tests.txt" 2>&1 || rc=1
  done
  grep -E "^\[  (PASSED|FAILED|SKIPPED) |^\[  FAILED  \]" "$out/parity_tests.txt" | tail -40
  return $rc
}

# Memory errors, shared-memory races and sync errors in the kernels the
# parity tests exercise hardest (multi-batch tiles, crops, empty models).
stage_sanitize() {
  local rc=0 tool
  command -v compute-sanitizer >/dev/null 2>&1 || { echo "no compute-sanitizer"; return 0; }
  for tool in memcheck racecheck synccheck; do
    compute-sanitizer --tool "$tool" --error-exitcode 9 \
      "$build/tests/watergs_gaussian_test" --gtest_filter='CudaRasterizer.DeepTileStackMatchesCpu:CudaRasterizer.CropRectsMatchCpu:CudaRasterizer.EmptyModelRendersBackground:CudaRasterizer.ShDegreeZeroModelMatchesCpu' \
      > "$out/sanitizer_$tool.txt" 2>&1 || { rc=1; echo "compute-sanitizer $tool: errors (sanitizer_$tool.txt)"; }
    # The device-resident embedding step (distortion scatter, decoder patch).
    compute-sanitizer --tool "$tool" --error-exitcode 9 \
      "$build/tests/watergs_watermark_test" --gtest_filter='EmbedderCuda.DeviceResident*' \
      > "$out/sanitizer_embed_$tool.txt" 2>&1 || { rc=1; echo "compute-sanitizer $tool: errors (sanitizer_embed_$tool.txt)"; }
  done
  return $rc
}

stage_bench() {
  {
    "$build/benchmarks/raster_benchmark" --device cuda --threads "$(nproc)"
    "$build/benchmarks/raster_benchmark" --device cuda --scenes 1000 --repeats 9
    "$build/benchmarks/train_benchmark" --device cuda --json "$out/train_cuda.json"
    "$build/benchmarks/decoder_benchmark" --device cuda 5
    # Embedding: the 1M-Gaussian 1 MP scene (issue 8's 10k-iteration target)
    # and the demo scene after a short GPU training run.
    "$build/benchmarks/embed_benchmark" --synthetic 1000000 \
      watermark/models/hidden_48.bin 20 cuda
    "$build/watergs" train --device cuda --workspace_path datasets_scripts/demo_scene \
      --output_path "$build/demo_gpu" --iterations 3000 --downscale 2 > /dev/null &&
      "$build/benchmarks/embed_benchmark" "$build/demo_gpu/point_cloud.ply" \
        datasets_scripts/demo_scene watermark/models/hidden_48.bin 30 2 cuda
  } > "$out/benchmarks.txt" 2>&1
  tail -40 "$out/benchmarks.txt"
}

for stage in $stages; do
  echo "== $stage"
  "stage_$stage" || status=1
done
exit $status
