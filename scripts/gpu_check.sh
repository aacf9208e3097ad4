#!/usr/bin/env bash
# GPU verification of the CUDA backend on a bare CUDA machine (nvcc, cuDNN,
# cuBLAS, compute-sanitizer; none of the project's Debian libraries, no
# package registry), in one call, from the bundle scripts/gpu_bundle.sh made
# of a build here:
#   bash scripts/gpu_check.sh [--bundle FILE] [--out DIR] [--deadline S]
#                             [STAGE ...]
# FILE defaults to .gpu/bundle.tar.xz (--gsplat: .gpu/gsplat.tar.xz), DIR to gpu_out, S (seconds for all
# stages together, each stage also capped) to 540. Stages, in this order
# when none is named:
#   parity    the CUDA parity tests of every module (*Cuda*:*CUDA*)
#   demo      the demo scene's train -> embed (--crop_size 0, the shipped
#             decoder) -> extract, all --device cuda
#   bench     raster_benchmark (with the 1M-Gaussian 1920x1080 scene),
#             train_benchmark, embed_benchmark (1M Gaussians, 1280x800),
#             decoder_benchmark of each decoder kind, all --device cuda
#   sanitize  compute-sanitizer memcheck, racecheck and synccheck on the
#             tests of the rasterizer, the device-resident embedding step
#             and the feature decoder twin
#   gsplat    (named only) watergs' 1M-Gaussian 1920x1080 raster figures,
#             then gsplat's on the same scene and card (scripts/gsplat_timing.py,
#             gsplat from --gsplat FILE, made by scripts/gsplat_bundle.sh; the
#             device's PyTorch, or a line saying there is none)
#   profile   (named only) Nsight Systems' kernel summary of 300 demo
#             embedding iterations (after the demo stage), and Nsight
#             Compute's per-kernel summary of the 1M-Gaussian 1920x1080
#             rasterizer benchmark's first iterations
# Logs: DIR/<stage>.txt and DIR/env.txt; a summary on stdout. Exit status:
# 0 when every stage ran clean, 1 when one failed, 2 on bad arguments or a
# bundle that cannot be placed.
set -uo pipefail
die() { echo "gpu_check: $*" >&2; exit 2; }
usage="gpu_check.sh [--bundle FILE] [--gsplat FILE] [--out DIR] [--deadline S] [parity] [demo] [bench] [sanitize] [gsplat] [profile]"
bundle=.gpu/bundle.tar.xz gsplat_bundle=.gpu/gsplat.tar.xz out=gpu_out deadline=540 stages=()
while [ $# -gt 0 ]; do
  case "$1" in
    --bundle|--gsplat|--out|--deadline)
      [ $# -ge 2 ] || die "$1 needs a value (usage: $usage)"
      case "$1" in
        --bundle) bundle="$2" ;;
        --gsplat) gsplat_bundle="$2" ;;
        --out) out="$2" ;;
        --deadline) [[ "$2" =~ ^[1-9][0-9]*$ ]] || die "--deadline: expected seconds > 0, got '$2'"
          deadline="$2" ;;
      esac
      shift 2 ;;
    -h|--help) awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; exit 0 ;;
    parity|demo|bench|sanitize|gsplat|profile) stages+=("$1"); shift ;;
    *) die "unknown argument '$1' (usage: $usage)" ;;
  esac
done
[ ${#stages[@]} -gt 0 ] || stages=(parity demo bench sanitize)
[ -f "$bundle" ] || die "no bundle '$bundle' (make it here with scripts/gpu_bundle.sh)"
case "$gsplat_bundle" in /*) ;; *) gsplat_bundle="$(pwd -P)/$gsplat_bundle" ;; esac
[ "${GPU_CHECK_PARSE_ONLY:-0}" = 1 ] && { echo "stages: ${stages[*]}; bundle $bundle; out $out; deadline $deadline"; exit 0; }

t0=$SECONDS
# Seconds a step may take: its cap, or what is left of the deadline.
lim() { local left=$((deadline - (SECONDS - t0))); [ "$left" -lt "$1" ] && echo $((left > 1 ? left : 1)) || echo "$1"; }
mkdir -p "$out"; out="$(cd "$out" && pwd -P)"
here="$(pwd -P)"
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
tar -xJf "$bundle" -C "$tmp" || die "cannot unpack $bundle"
src=$(sed -n 1p "$tmp/paths"); build=$(sed -n 2p "$tmp/paths")
# The sources go back where the build was made (compiled-in paths), unless
# this checkout is already there.
if [ -d "$src" ] && [ "$(cd "$src" && pwd -P)" = "$here" ]; then :
elif [ ! -e "$src" ]; then mkdir -p "$(dirname "$src")" && mv "$tmp/repo" "$src" || die "cannot place the sources at $src"
else die "$src exists and is not this checkout: refusing to touch it"; fi
mkdir -p "$build" && cp -r "$tmp/build/." "$build/" || die "cannot place the build at $build"
libs="$tmp/libs"
# The machine's own cuDNN 9 and cuBLAS 13 (system or pip-installed).
for d in $(find /usr/local /usr/lib /opt -name 'libcudnn.so.9' -o -name 'libcublas.so.13' 2>/dev/null | xargs -r -n1 dirname | sort -u); do
  libs="$libs:$d"
done
export LD_LIBRARY_PATH="$libs${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
export WATERGS_BIN="$build/plugin/watergs"
cd "$src"
W="$build/plugin/watergs" T="$build/tests" B="$build/benchmarks"
{ date; nvidia-smi; echo "LD_LIBRARY_PATH=$LD_LIBRARY_PATH"
  for f in "$W" "$T"/watergs_*_test "$B"/*_benchmark; do ldd "$f" | grep "not found" | sed "s|^|$(basename "$f"): |"; done
} > "$out/env.txt" 2>&1

# Runs "$@" with a time limit of `lim $1` seconds, logging its exit status.
step() { local cap=$1 name=$2; shift 2; local s=$SECONDS
  timeout "$(lim "$cap")" "$@"; local rc=$?
  echo "== $name: exit $rc in $((SECONDS - s)) s"; return $rc; }

stage_parity() {
  local rc=0 m
  for m in gaussian distortion watermark plugin; do
    step 120 "$m parity" "$T/watergs_${m}_test" --gtest_filter='*Cuda*:*CUDA*' || rc=1
  done > "$out/parity.txt" 2>&1
  grep -E "^\[  FAILED  \]|^\[  PASSED  \]|^== " "$out/parity.txt"
  return $rc
}

stage_demo() {
  local rc=0 sc=datasets_scripts/demo_scene dec=watermark/models/decoder_48.bin o="$tmp/demo"
  { step 150 train "$W" train --device cuda --workspace_path $sc --output_path "$o/train" --downscale 2 \
      --iterations 2000 --densify_until_iter 1000 --split train --test_iterations 2000 || rc=1
    step 150 embed "$W" embed --device cuda --input_path "$o/train/point_cloud.ply" --workspace_path $sc \
      --downscale 2 --decoder $dec --message text:WGS-26 --output_path "$o/wm.ply" --split train || rc=1
    step 40 "extract point_cloud.ply" "$W" extract --device cuda --input_path "$o/train/point_cloud.ply" \
      --workspace_path $sc --downscale 2 --decoder $dec --message text:WGS-26 || rc=1
    # Read blind and as the owner (embed's default reading since issue 36).
    step 40 "extract wm.ply" "$W" extract --device cuda --input_path "$o/wm.ply" --workspace_path $sc \
      --downscale 2 --decoder $dec --message text:WGS-26 --raw_path "$o/train/point_cloud.ply" || rc=1
    # Held-out views and 48 free viewpoints apart (issue 36's figures).
    step 40 "extract wm.ply held-out" "$W" extract --device cuda --input_path "$o/wm.ply" --workspace_path $sc \
      --downscale 2 --decoder $dec --message text:WGS-26 --raw_path "$o/train/point_cloud.ply" --split test || rc=1
    step 40 "extract wm.ply 48 free" "$W" extract --device cuda --input_path "$o/wm.ply" --workspace_path $sc \
      --downscale 2 --decoder $dec --message text:WGS-26 --raw_path "$o/train/point_cloud.ply" \
      --num_views 48 --seed 1 || rc=1
  } > "$tmp/demo_raw.txt" 2>&1
  # Progress bars redraw with \r: keep the lines that are not bars.
  tr '\r' '\n' < "$tmp/demo_raw.txt" | grep -v -E '^(train|embed) \[' > "$out/demo.txt"
  grep -E "^== |BER|verdict|it/s|device" "$out/demo.txt"
  return $rc
}

stage_bench() {
  local rc=0
  { step 90 raster_benchmark "$B/raster_benchmark" --device cuda --scenes 1000 --repeats 9 \
      --write_scene "$tmp/scene" || rc=1
    step 60 train_benchmark "$B/train_benchmark" --device cuda || rc=1
    step 120 embed_benchmark "$B/embed_benchmark" --synthetic 1000000 watermark/models/decoder_48.bin 20 cuda || rc=1
    step 90 decoder_benchmark "$B/decoder_benchmark" --device cuda --repeats 5 \
      watermark/models/hidden_48.bin watermark/models/decoder_48.bin || rc=1
  } > "$out/bench.txt" 2>&1
  grep -E "^== |1M|resident|it/s|10k|decoder" "$out/bench.txt" | head -40
  return $rc
}

stage_sanitize() {
  local rc=0 tool
  for tool in memcheck racecheck synccheck; do
    # racecheck is the slow tool: the embedding tests took over 60 s under
    # it on an H200.
    local cap=60; [ $tool = racecheck ] && cap=240
    step 60 "$tool rasterizer" compute-sanitizer --tool $tool --error-exitcode 9 \
      "$T/watergs_gaussian_test" --gtest_filter='CudaRasterizer.*' || rc=1
    step $cap "$tool embedding" compute-sanitizer --tool $tool --error-exitcode 9 \
      "$T/watergs_watermark_test" --gtest_filter='EmbedderCuda.DeviceResident*:CudaFeatureDecoder.*' || rc=1
  done > "$out/sanitize.txt" 2>&1
  grep -E "^== |ERROR SUMMARY" "$out/sanitize.txt"
  return $rc
}

stage_gsplat() {
  local rc=0 g="$tmp/gsplat" scene="$tmp/scene"
  { echo "python3: $(command -v python3 || echo none)"
    python3 -c 'import torch; print("torch", torch.__version__, "CUDA", torch.version.cuda, "available", torch.cuda.is_available())' 2>&1 | tail -1
    # The bench stage of this call wrote the scene and timed watergs on it already.
    if [ ! -f "$scene/scene_1m.ply" ]; then
      step 150 "raster_benchmark 1M (watergs; writes the scene)" "$B/raster_benchmark" --device cuda \
        --scenes 1000 --repeats 9 --write_scene "$scene" || rc=1
    fi
    if [ ! -f "$gsplat_bundle" ]; then
      echo "gsplat: no $gsplat_bundle (make it here: bash scripts/gsplat_bundle.sh --source GSPLAT_GIT)"; rc=1
    elif ! python3 -c 'import sys, torch; sys.exit(0 if torch.cuda.is_available() else 1)' 2>/dev/null; then
      echo "gsplat: no PyTorch with CUDA on this machine; gsplat's CUDA extension builds against it (not measured)"
    else
      mkdir -p "$g" && tar -xJf "$gsplat_bundle" -C "$g"
      # gsplat JIT-builds its extension on first import (minutes; 16 jobs).
      step 420 "gsplat build + timing" env PYTHONPATH="$g/gsplat:$g/deps/usr/lib/python3/dist-packages" \
        PATH="$g/deps/usr/bin:$PATH" TORCH_EXTENSIONS_DIR="$tmp/torch_ext" MAX_JOBS=16 \
        python3 scripts/gsplat_timing.py "$scene" --repeats 9 || rc=1
    fi
  } > "$out/gsplat.txt" 2>&1
  grep -E "^== |^gsplat|^torch|resident|1M" "$out/gsplat.txt" | head -20
  return $rc
}

# The tools where CUDA images keep them, when not on PATH.
find_tool() { command -v "$1" 2>/dev/null ||
  ls /usr/local/cuda/bin/"$1" /opt/nvidia/nsight-*/*/bin/"$1" /opt/nvidia/nsight-*/bin/"$1" 2>/dev/null | head -1; }

stage_profile() {
  local rc=0 sc=datasets_scripts/demo_scene dec=watermark/models/decoder_48.bin nsys ncu
  nsys=$(find_tool nsys) ncu=$(find_tool ncu)
  # A missing tool is the image's, not a failure: said, and skipped.
  { if [ -z "$nsys" ]; then echo "profile: no nsys on this machine (skipped)"
    elif [ ! -f "$tmp/demo/train/point_cloud.ply" ]; then echo "profile: run the demo stage first (demo profile)"; rc=1
    else
      step 120 "nsys embed" "$nsys" profile --stats=true --force-overwrite true -o "$tmp/embed_profile" \
        "$W" embed --device cuda --input_path "$tmp/demo/train/point_cloud.ply" --workspace_path $sc \
        --downscale 2 --decoder $dec --message text:WGS-26 --output_path "$tmp/profiled.ply" --iterations 300 \
        --crop_size 0 --free_view_fraction 0.5 --gamma 0.03 --densify off --check_every 100000 || rc=1
    fi
    if [ -z "$ncu" ]; then echo "profile: no ncu on this machine (skipped)"
    else
      step 150 "ncu raster" "$ncu" --print-summary per-kernel --launch-skip 40 --launch-count 40 \
        "$B/raster_benchmark" --device cuda --scenes 1000 --repeats 1 || rc=1
    fi
  } > "$tmp/profile_raw.txt" 2>&1
  tr '\r' '\n' < "$tmp/profile_raw.txt" | grep -v -E '^embed \[' > "$out/profile.txt"
  grep -E "^== |^profile:" "$out/profile.txt"
  return $rc
}

status=0
for st in "${stages[@]}"; do
  echo "==== $st ($((SECONDS - t0)) s)"
  "stage_$st" || status=1
done
echo "==== done in $((SECONDS - t0)) s, status $status"
exit $status
