#!/usr/bin/env bash
# Downloads NeRF-synthetic's lego (the scene GuardSplat and 3D-GSW report on: 100 training and 200
# test views of 800x800 RGBA, transforms_{train,val,test}.json) and writes it as a COLMAP workspace
# with `watergs transforms_importer`:
#   OUT/lego/source/           the scene as published (PNGs, transforms_*.json; depth/normal maps left out)
#   OUT/lego/workspace/        images/{train,test}/ on a white background, sparse/0 (random initial
#                              points), test_views.txt (the 200 test views, held out by --split train)
# Usage: bash datasets_scripts/download_nerf_synthetic.sh [--from DIR] [OUT_DIR (default data/nerf_synthetic)]
#   --from DIR  a local copy: DIR holds lego/ directly or under nerf_synthetic/ or data/nerf_synthetic/
# Source (public copy, the original is on Google Drive): github luo-ziyuan/CopyRNeRF-code,
# data/nerf_synthetic/lego, fetched with a sparse, blob-filtered git clone (~170 MB).
# WATERGS_BIN (default build/plugin/watergs) is the importer; OUT/lego/photos.sha256 names the files.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib_download.sh"
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bin="${WATERGS_BIN:-$root/build/plugin/watergs}"
from_option "$@"
shift "$from_shift"
out_dir="${1:-data/nerf_synthetic}"
scene="$out_dir/lego"
[ -x "$bin" ] || die "$bin: not built (cmake --build build, or set WATERGS_BIN)"
mkdir -p "$scene"

if [ ! -f "$scene/source/transforms_test.json" ]; then
  if [ -z "$from_dir" ]; then
    clone="$out_dir/.downloads/CopyRNeRF-code"
    sparse_clone https://github.com/luo-ziyuan/CopyRNeRF-code.git "$clone" \
      '/data/nerf_synthetic/lego/*.json' '/data/nerf_synthetic/lego/train/r_*[0-9].png' \
      '/data/nerf_synthetic/lego/test/r_*[0-9].png' '/data/nerf_synthetic/lego/val/r_*[0-9].png'
    from_dir="$clone"
  fi
  source_dir=""
  for prefix in "" nerf_synthetic/ data/nerf_synthetic/; do
    [ -f "$from_dir/${prefix}lego/transforms_train.json" ] && source_dir="$from_dir/${prefix}lego" && break
  done
  [ -n "$source_dir" ] || die "$from_dir holds no lego/transforms_train.json (nor under nerf_synthetic/)"
  scratch="$(mktemp -d "$scene/source.copying.XXXXXX")"
  (cd "$source_dir" && find . -name 'transforms_*.json' -o -regex '.*/r_[0-9]+\.png') \
    | (cd "$source_dir" && xargs -d '\n' cp --parents -t "$scratch") || die "cannot copy $source_dir"
  [ "$(find "$scratch/train" -name '*.png' | wc -l)" -eq 100 ] || die "$source_dir: expected 100 training PNGs"
  [ "$(find "$scratch/test" -name '*.png' | wc -l)" -eq 200 ] || die "$source_dir: expected 200 test PNGs"
  rm -rf "$scene/source"
  mv "$scratch" "$scene/source"
fi
(cd "$scene/source" && find . -type f -printf '%P\n' | LC_ALL=C sort | xargs -d '\n' sha256sum) \
  > "$scene/photos.sha256"
log "manifest: $scene/photos.sha256 ($(wc -l < "$scene/photos.sha256") files)"
if [ ! -f "$scene/workspace/test_views.txt" ]; then
  "$bin" transforms_importer --transforms_path "$scene/source" --output_path "$scene/workspace" \
    --background white
fi
log "done: $scene/workspace (train with --split train --background white)"
