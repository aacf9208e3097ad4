#!/usr/bin/env bash
# Downloads Mip-NeRF 360's bonsai as a public copy at 800x533 (252 photos, about a quarter of the
# original 3118x2078; the copy's own sparse models register only 3 photos, so reconstruct it):
#   OUT/bonsai_800/images/        the 252 JPEGs (DSCF5605..DSCF5856, capture order)
#   OUT/bonsai_800/photos.sha256  their SHA-256, checked against results/mipnerf360_bonsai/photos.sha256
# then: watergs reconstruct --image_path OUT/bonsai_800/images --workspace_path WS
# Usage: bash datasets_scripts/download_bonsai_800.sh [--from DIR] [OUT_DIR (default data/mipnerf360)]
#   --from DIR  a local clone or folder holding the JPEGs at its top level
# Source: github EricXu23/Bonsaidownload (the photos at its top level), fetched with a sparse,
# blob-filtered git clone (~21 MB). The full-resolution set: download_mipnerf360.sh bonsai.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib_download.sh"
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
from_option "$@"
shift "$from_shift"
out_dir="${1:-data/mipnerf360}"
scene="$out_dir/bonsai_800"
manifest="$root/results/mipnerf360_bonsai/photos.sha256"
mkdir -p "$scene"
if [ ! -f "$scene/photos.sha256" ]; then
  if [ -z "$from_dir" ]; then
    clone="$out_dir/.downloads/Bonsaidownload"
    sparse_clone https://github.com/EricXu23/Bonsaidownload.git "$clone" '/DSCF*.JPG'
    from_dir="$clone"
  fi
  scratch="$(mktemp -d "$scene/images.copying.XXXXXX")"
  find "$from_dir" -maxdepth 1 -name 'DSCF*.JPG' -exec cp -t "$scratch" {} + || die "cannot copy from $from_dir"
  count="$(find "$scratch" -name '*.JPG' | wc -l)"
  [ "$count" -eq 252 ] || die "$from_dir: expected 252 photos DSCF*.JPG, found $count"
  rm -rf "$scene/images"
  mv "$scratch" "$scene/images"
  (cd "$scene/images" && sha256sum ./*.JPG | sed 's#  \./#  #') > "$scene/photos.sha256.part"
  mv "$scene/photos.sha256.part" "$scene/photos.sha256"
fi
if [ -f "$manifest" ]; then
  cmp -s "$scene/photos.sha256" "$manifest" ||
    die "$scene/photos.sha256 differs from $manifest (another copy of bonsai?)"
  log "photos match $manifest"
fi
log "done: $scene/images (next: watergs reconstruct --image_path $scene/images --workspace_path WS)"
