#!/usr/bin/env bash
# Downloads the Tanks&Temples scenes train and truck as prepared by the 3D Gaussian Splatting authors
# (tandt_db.zip, about 650 MB, which also holds Deep Blending's drjohnson and playroom) and lays them out as
# COLMAP workspaces for watergs:
#   OUT/train/images/   (301 images, about 1K wide)   OUT/train/sparse/0/   undistorted PINHOLE model
#   OUT/truck/images/   (251 images, about 1K wide)   OUT/truck/sparse/0/
# No downscaled folders ship with this archive (the images are already about 1K wide); every 8th image is
# the held-out view. Pass --with-db to also lay out the Deep Blending scenes (drjohnson, playroom).
#
# Usage: bash datasets_scripts/download_tandt.sh [--with-db] [OUT_DIR (default data/tandt)]
# Source: https://repo-sam.inria.fr/fungraph/3d-gaussian-splatting/ ("SfM data sets for Tanks&Temples and
# Deep Blending"), archive layout tandt/{train,truck}/{images,sparse/0} and db/{drjohnson,playroom}/...
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib_download.sh"

readonly archive_url="https://repo-sam.inria.fr/fungraph/3d-gaussian-splatting/datasets/input/tandt_db.zip"
with_db=0
if [ "${1:-}" == "--with-db" ]; then with_db=1; shift; fi
out_dir="${1:-data/tandt}"

require_tools unzip md5sum
cache="${WATERGS_DOWNLOAD_CACHE:-$out_dir/.downloads}"
zip="$cache/tandt_db.zip"
fetch "$archive_url" "$zip"

folders=(tandt/train tandt/truck)
[ "$with_db" -eq 1 ] && folders+=(db/drjohnson db/playroom)
mkdir -p "$out_dir"
for folder in "${folders[@]}"; do
  scene="$(basename "$folder")"
  unpack_folder "$zip" "$folder" "$out_dir/$scene"
  check_colmap_scene "$out_dir/$scene"
done
log "done: ${#folders[@]} scene(s) in $out_dir; remove $cache to free the archive's space"
