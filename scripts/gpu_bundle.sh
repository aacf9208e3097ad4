#!/usr/bin/env bash
# Packs a CUDA build made here (README's build on a machine with nvcc, no GPU
# needed) for a bare CUDA machine (nvcc, cuDNN, cuBLAS, compute-sanitizer, no
# Eigen/OpenCV/Ceres/glog/Boost, no package registry), where
# scripts/gpu_check.sh unpacks and runs it in one call:
#   bash scripts/gpu_bundle.sh [--build DIR] [--out DIR]      (project root)
# DIR defaults: build, .gpu (an out folder in the checkout ignores itself).
# Bundle layout (OUT/bundle.tar.xz):
#   paths            line 1: the source root, line 2: the build folder, both
#                    absolute: gpu_check.sh puts them back at those paths, so
#                    the paths compiled into the tests (WATERGS_SOURCE_DIR,
#                    WATERGS_BINARY_DIR) hold there
#   repo/            the tracked sources (not results/ or docs/)
#   build/plugin/watergs, build/tests/watergs_*_test,
#   build/benchmarks/*_benchmark
#   libs/            every shared library those binaries load, except what
#                    any glibc system has (libc, libm, libstdc++, ...), the
#                    driver's libcuda and the CUDA machine's cuDNN/cuBLAS;
#                    Debian's GDAL replaced by a stub (below)
set -euo pipefail
die() { echo "gpu_bundle: $*" >&2; exit 2; }
src="$(pwd -P)"
build=build out=.gpu
while [ $# -gt 0 ]; do
  case "$1" in
    --build) [ $# -ge 2 ] || die "--build needs a folder"; build="$2"; shift 2 ;;
    --out) [ $# -ge 2 ] || die "--out needs a folder"; out="$2"; shift 2 ;;
    -h|--help) awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; exit 0 ;;
    *) die "unknown argument '$1' (usage: gpu_bundle.sh [--build DIR] [--out DIR])" ;;
  esac
done
[ -e "$src/.git" ] || die "run from the project's root (no .git here)"
[ -d "$build" ] || die "no build folder '$build': build first (README)"
build="$(cd "$build" && pwd -P)"
[ -x "$build/plugin/watergs" ] || die "no $build/plugin/watergs: build first (README)"
ls "$build"/tests/watergs_*_test > /dev/null 2>&1 || die "no test binaries in $build/tests"
stage=$(mktemp -d)
trap 'rm -rf "$stage"' EXIT
mkdir -p "$stage/repo" "$stage/build/plugin" "$stage/build/tests" "$stage/build/benchmarks" "$stage/libs"
git -C "$src" ls-files -z | grep -z -v -E '^(results|docs)/' |
  (cd "$src" && tar --null -cf - -T -) | tar -xf - -C "$stage/repo"
cp "$build/plugin/watergs" "$stage/build/plugin/"
cp "$build"/tests/watergs_*_test "$stage/build/tests/"
for f in "$build"/benchmarks/*_benchmark; do [ -x "$f" ] && cp "$f" "$stage/build/benchmarks/"; done
# Debian's OpenCV imgcodecs links GDAL (a 150 MB tree of libraries) for the
# few functions it calls only for IMREAD_LOAD_GDAL, which watergs never asks
# for: a stub library of that soname defining each of them (returning 0)
# satisfies the loader.
gdal=$(readlink -f /lib/x86_64-linux-gnu/libgdal.so.* 2>/dev/null | head -1 || true)
if [ -n "$gdal" ]; then
  soname=$(objdump -p "$gdal" | awk '$1=="SONAME"{print $2}')
  for l in /lib/x86_64-linux-gnu/libopencv_*.so.4*; do
    readelf --dyn-syms -W "$l" | awk '$7=="UND"{s=$8; sub(/@.*/,"",s); print s}'
  done | sort -u > "$stage/undefined"
  nm -D --defined-only "$gdal" | awk 'NF==3{s=$3; sub(/@.*/,"",s); print s}' | sort -u |
    comm -12 - "$stage/undefined" | awk '{print "void* " $1 "(void) { return 0; }"}' > "$stage/stub.c"
  gcc -shared -fPIC -O1 -Wl,-soname,"$soname" -o "$stage/libs/$soname" "$stage/stub.c"
  rm -f "$stage/undefined" "$stage/stub.c"
fi
# Libraries a bare CUDA machine has: glibc's, the compiler runtime, the
# driver's, and the CUDA libraries too big to carry (cuDNN, cuBLAS).
skip='^(linux-vdso|ld-linux|libc\.so|libm\.so|libpthread|libdl\.so|librt\.so|libstdc\+\+|libgcc_s|libcuda\.so|libcudnn|libcublas)'
for f in "$stage"/build/plugin/* "$stage"/build/tests/* "$stage"/build/benchmarks/*; do
  [ -f "$f" ] && LD_LIBRARY_PATH="$stage/libs" ldd "$f" 2>/dev/null || true
done | awk '/=> \//{print $1, $3}' | sort -u |
  while read -r name path; do
    [[ "$name" =~ $skip ]] && continue
    [ -e "$stage/libs/$name" ] || cp -L "$path" "$stage/libs/$name"
  done
printf '%s\n%s\n' "$src" "$build" > "$stage/paths"
mkdir -p "$out"
out="$(cd "$out" && pwd -P)"
# An out folder inside the checkout ignores itself (a .gitignore of "*"),
# which touches no git metadata another worktree shares.
case "$out" in "$src"/*) printf '*\n' > "$out/.gitignore" ;; esac
# GPU_BUNDLE_XZ_LEVEL: xz's preset (default 6; the test's stand-in bundle uses 0).
tar -C "$stage" -cf - paths repo build libs | xz -T2 "-${GPU_BUNDLE_XZ_LEVEL:-6}" > "$out/bundle.tar.xz"
echo "gpu_bundle: $(du -h "$out/bundle.tar.xz" | cut -f1) in $out/bundle.tar.xz" \
  "($(ls "$stage/libs" | wc -l) libraries); on the GPU machine: bash scripts/gpu_check.sh --bundle ${out#"$src"/}/bundle.tar.xz"
