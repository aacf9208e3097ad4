#!/usr/bin/env bash
# Downloads the Mip-NeRF 360 scenes and lays them out as COLMAP workspaces for watergs:
#   OUT/<scene>/images/                 full-resolution photographs
#   OUT/<scene>/images_2|4|8/           downscaled copies shipped by the dataset (same file names)
#   OUT/<scene>/sparse/0/               COLMAP model
#   OUT/<scene>/poses_bounds.npy        kept for other tools
# 360_v2.zip (several GB; sizes were not verifiable offline): bicycle bonsai counter garden kitchen room stump
# 360_extra_scenes.zip (only fetched when flowers or treehill are asked for): flowers treehill
# Convention of the 3DGS paper: outdoor scenes at images_4, indoor at images_2; every 8th image held out.
#
# Usage: bash datasets_scripts/download_mipnerf360.sh [OUT_DIR (default data/mipnerf360)] [scene ...]
# Source: https://jonbarron.info/mipnerf360/ (files on storage.googleapis.com/gresearch/refraw360/).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib_download.sh"

readonly main_scenes=(bicycle bonsai counter garden kitchen room stump)
readonly extra_scenes=(flowers treehill)
readonly base_url="https://storage.googleapis.com/gresearch/refraw360"
out_dir="${1:-data/mipnerf360}"
[ $# -gt 0 ] && shift
scenes=("$@")
[ ${#scenes[@]} -eq 0 ] && scenes=("${main_scenes[@]}" "${extra_scenes[@]}")

require_tools unzip md5sum
cache="${WATERGS_DOWNLOAD_CACHE:-$out_dir/.downloads}"

# archive_of SCENE: the zip that holds SCENE.
archive_of() {
  if [[ " ${main_scenes[*]} " == *" $1 "* ]]; then echo 360_v2
  elif [[ " ${extra_scenes[*]} " == *" $1 "* ]]; then echo 360_extra_scenes
  else die "unknown Mip-NeRF 360 scene '$1' (known: ${main_scenes[*]} ${extra_scenes[*]})"; fi
}

declare -A needed=()
for scene in "${scenes[@]}"; do needed[$(archive_of "$scene")]=1; done
for archive in "${!needed[@]}"; do
  fetch "$base_url/$archive.zip" "$cache/$archive.zip"
done

mkdir -p "$out_dir"
for scene in "${scenes[@]}"; do
  unpack_folder "$cache/$(archive_of "$scene").zip" "$scene" "$out_dir/$scene"
  match_downscaled_names "$out_dir/$scene"
  check_colmap_scene "$out_dir/$scene"
done
log "done: ${#scenes[@]} scene(s) in $out_dir; remove $cache to free the archives' space"
