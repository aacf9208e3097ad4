#!/usr/bin/env bash
# Downloads the LLFF forward-facing scenes (NeRF's nerf_llff_data.zip, roughly 2 GB) and lays them out as
# COLMAP workspaces for watergs:
#   OUT/<scene>/images/        full-resolution photographs (4032x3024)
#   OUT/<scene>/images_4/      1008x756, images_8/ 504x378 (shipped by the dataset; file names made equal
#                              to the names in sparse/0 so `--downscale 4|8` reads them directly)
#   OUT/<scene>/sparse/0/      COLMAP model (cameras.bin, images.bin, points3D.bin)
#   OUT/<scene>/poses_bounds.npy   kept for other tools
# Scenes: fern flower fortress horns leaves orchids room trex. Held-out views: every 8th image (--split train).
#
# Usage: bash datasets_scripts/download_llff.sh [--from DIR] [OUT_DIR (default data/llff)] [scene ...]
#   --from DIR  lay out the scenes from a local copy instead of the archive: DIR holds <scene>/ folders
#               directly or under nerf_llff_data/, data/ or data/nerf_llff_data/ (an unpacked archive, or
#               a clone of a repository that carries LLFF scenes, e.g. github luo-ziyuan/CopyRNeRF-code for
#               fern: its images.bin is missing, see docs/reproduce.md; the room and trex of
#               bwnebs1/23-2_DSL_Modeling_3D_Style_with_NeRF are style-transferred, not photos).
# Every scene gets OUT/<scene>/photos.sha256, the SHA-256 of each photo and model file, so a figure can
# name the exact files it came from (results/real_llff/ keeps a copy; the photos are not committed).
# Source: the NeRF authors' Google Drive folder
#   https://drive.google.com/drive/folders/128yBriW1IG_3NJ5Rp7APSTZsJqdJdfc1 (file nerf_llff_data.zip).
# If the automatic Google Drive download is refused (quota), download nerf_llff_data.zip by hand into
# OUT_DIR/.downloads/ and run the script again.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib_download.sh"

readonly all_scenes=(fern flower fortress horns leaves orchids room trex)
readonly gdrive_id="16VnMcF1KJYxN9QId6TClMsZRahHNMW5g"  # nerf_llff_data.zip
from_option "$@"
shift "$from_shift"
out_dir="${1:-data/llff}"
[ $# -gt 0 ] && shift
scenes=("$@")
[ ${#scenes[@]} -eq 0 ] && scenes=("${all_scenes[@]}")
for scene in "${scenes[@]}"; do
  [[ " ${all_scenes[*]} " == *" $scene "* ]] || die "unknown LLFF scene '$scene' (known: ${all_scenes[*]})"
done

# scene_in_copy SCENE: the folder of SCENE inside --from's folder, or nothing.
scene_in_copy() {
  local prefix
  for prefix in "" nerf_llff_data/ data/ data/nerf_llff_data/; do
    if [ -d "$from_dir/$prefix$1/images" ]; then
      echo "$from_dir/$prefix$1"
      return
    fi
  done
}

mkdir -p "$out_dir"
if [ -n "$from_dir" ]; then
  require_tools sha256sum
  for scene in "${scenes[@]}"; do
    source_dir="$(scene_in_copy "$scene")"
    [ -n "$source_dir" ] || die "$from_dir holds no $scene/images (nor under nerf_llff_data/, data/)"
    copy_folder "$source_dir" "$out_dir/$scene"
  done
else
  require_tools unzip md5sum sha256sum
  cache="${WATERGS_DOWNLOAD_CACHE:-$out_dir/.downloads}"
  zip="$cache/nerf_llff_data.zip"
  fetch_gdrive "$gdrive_id" "$zip"
  for scene in "${scenes[@]}"; do
    unpack_folder "$zip" "nerf_llff_data/$scene" "$out_dir/$scene"
  done
fi
for scene in "${scenes[@]}"; do
  rm -f "$out_dir/$scene/database.db"  # COLMAP's matching database: large and not needed for training
  match_downscaled_names "$out_dir/$scene"
  write_manifest "$out_dir/$scene"
  check_colmap_scene "$out_dir/$scene" ${from_dir:+--photos_only_ok}
done
if [ -n "$from_dir" ]; then
  log "done: ${#scenes[@]} scene(s) in $out_dir (from $from_dir)"
else
  log "done: ${#scenes[@]} scene(s) in $out_dir; remove $cache to free the archive's space"
fi
