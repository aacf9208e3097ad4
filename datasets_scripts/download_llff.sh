#!/usr/bin/env bash
# Downloads the LLFF forward-facing scenes (NeRF's nerf_llff_data.zip, roughly 2 GB) and lays them out as
# COLMAP workspaces for watergs:
#   OUT/<scene>/images/        full-resolution photographs (4032x3024)
#   OUT/<scene>/images_4/      1008x756, images_8/ 504x378 (shipped by the dataset; file names made equal
#                              to the names in sparse/0 so `--downscale 4|8` reads them directly)
#   OUT/<scene>/sparse/0/      COLMAP model (cameras.bin, images.bin, points3D.bin)
#   OUT/<scene>/poses_bounds.npy   kept for other tools
# Scenes: fern flower fortress horns leaves orchids room trex. Held-out views: every 8th image (--eval).
#
# Usage: bash datasets_scripts/download_llff.sh [OUT_DIR (default data/llff)] [scene ...]
# Source: the NeRF authors' Google Drive folder
#   https://drive.google.com/drive/folders/128yBriW1IG_3NJ5Rp7APSTZsJqdJdfc1 (file nerf_llff_data.zip).
# If the automatic Google Drive download is refused (quota), download nerf_llff_data.zip by hand into
# OUT_DIR/.downloads/ and run the script again.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib_download.sh"

readonly all_scenes=(fern flower fortress horns leaves orchids room trex)
readonly gdrive_id="16VnMcF1KJYxN9QId6TClMsZRahHNMW5g"  # nerf_llff_data.zip
out_dir="${1:-data/llff}"
[ $# -gt 0 ] && shift
scenes=("$@")
[ ${#scenes[@]} -eq 0 ] && scenes=("${all_scenes[@]}")
for scene in "${scenes[@]}"; do
  [[ " ${all_scenes[*]} " == *" $scene "* ]] || die "unknown LLFF scene '$scene' (known: ${all_scenes[*]})"
done

require_tools unzip md5sum
cache="${WATERGS_DOWNLOAD_CACHE:-$out_dir/.downloads}"
zip="$cache/nerf_llff_data.zip"
fetch_gdrive "$gdrive_id" "$zip"
mkdir -p "$out_dir"
for scene in "${scenes[@]}"; do
  unpack_folder "$zip" "nerf_llff_data/$scene" "$out_dir/$scene"
  rm -f "$out_dir/$scene/database.db"  # COLMAP's matching database: large and not needed for training
  match_downscaled_names "$out_dir/$scene"
  check_colmap_scene "$out_dir/$scene"
done
log "done: ${#scenes[@]} scene(s) in $out_dir; remove $cache to free the archive's space"
