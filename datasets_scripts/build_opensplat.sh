#!/usr/bin/env bash
# A third-party splat for issue 53's check: OpenSplat built from its public source (CPU, Debian's
# libtorch) and trained on a copy of a COLMAP workspace in its own default frame.
#   build_opensplat.sh [--from MIRRORS] OUT [WORKSPACE] [ITERATIONS]
# MIRRORS: a folder holding local git clones named pierotofy+OpenSplat, nlohmann+json,
# jlblancoc+nanoflann and jarro2783+cxxopts (each a git directory or a folder with one in repo/);
# without it they are cloned from GitHub. OpenSplat's CMake downloads its header-only dependencies at
# configure time; they are given to it from those clones instead, at the tags it names.
# Writes OUT/src, OUT/build/opensplat, OUT/ws (the workspace copy), OUT/splat.ply, OUT/train.log.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib_download.sh"
from_option "$@"
shift "$from_shift"
out="${1:?usage: build_opensplat.sh [--from MIRRORS] OUT [WORKSPACE] [ITERATIONS]}"
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
ws="${2:-$root/datasets_scripts/demo_scene}"
iterations="${3:-2000}"
opensplat_commit=15b7e80  # OpenSplat 1.1.5, the version results/third_party/opensplat_demo/ used
require_tools git cmake make
[ -f /usr/lib/x86_64-linux-gnu/cmake/Torch/TorchConfig.cmake ] ||
  die "libtorch is not installed (Debian: apt-get install libtorch-dev libopencv-dev)"
[ -d "$ws/sparse" ] && [ -d "$ws/images" ] || die "$ws: not a COLMAP workspace (images/, sparse/)"
mkdir -p "$out"
out="$(cd "$out" && pwd)"

# clone_at NAME URL REV DEST: DEST checked out at REV, from the mirror when --from was given.
clone_at() {
  local name="$1" url="$2" rev="$3" dest="$4" src
  src="$url"
  if [ -n "$from_dir" ]; then
    src="$from_dir/$name"
    [ -d "$src/repo" ] && src="$src/repo"
    [ -d "$src" ] || die "$src: no such clone (--from)"
  fi
  if [ ! -d "$dest/.git" ]; then
    log "cloning $src at $rev"
    git clone -q "$src" "$dest" || die "git clone $src failed"
  fi
  git -C "$dest" checkout -q "$rev" || die "$dest: no revision $rev"
}

clone_at pierotofy+OpenSplat https://github.com/pierotofy/OpenSplat "$opensplat_commit" "$out/src"
clone_at nlohmann+json https://github.com/nlohmann/json v3.11.3 "$out/deps/json"
clone_at jlblancoc+nanoflann https://github.com/jlblancoc/nanoflann v1.5.5 "$out/deps/nanoflann"
clone_at jarro2783+cxxopts https://github.com/jarro2783/cxxopts v3.2.0 "$out/deps/cxxopts"

if [ ! -x "$out/build/opensplat" ]; then
  log "building OpenSplat (CPU) in $out/build"
  cmake -S "$out/src" -B "$out/build" -DGPU_RUNTIME=CPU -DCMAKE_BUILD_TYPE=Release \
    -DFETCHCONTENT_FULLY_DISCONNECTED=ON \
    -DFETCHCONTENT_SOURCE_DIR_NLOHMANN_JSON="$out/deps/json" \
    -DFETCHCONTENT_SOURCE_DIR_NANOFLANN="$out/deps/nanoflann" \
    -DFETCHCONTENT_SOURCE_DIR_CXXOPTS="$out/deps/cxxopts" > "$out/configure.log" 2>&1 ||
    die "configure failed (see $out/configure.log)"
  cmake --build "$out/build" -j"$(nproc)" --target opensplat > "$out/build.log" 2>&1 ||
    die "build failed (see $out/build.log)"
fi

# OpenSplat reads WORKSPACE/images and WORKSPACE/sparse/0 (or sparse/); a copy keeps its outputs out
# of the source workspace.
rm -rf "$out/ws"
cp -r "$ws" "$out/ws"
log "training $iterations iterations on $ws (log: $out/train.log)"
t0=$SECONDS
(cd "$out" && ./build/opensplat ws --cpu -n "$iterations" -d 2 --resolution-schedule 500 \
  -o "$out/splat.ply") > "$out/train.log" 2>&1 || die "opensplat failed (see $out/train.log)"
echo "opensplat: $((SECONDS - t0)) s on $(nproc) cores ($(grep -m1 'model name' /proc/cpuinfo |
  cut -d: -f2 | xargs))" >> "$out/train.log"
log "wrote $out/splat.ply"
