#!/usr/bin/env bash
# Downloads COCO 2017 images for training the watermark decoder (`watergs train_decoder`) and writes
# them as flat folders, the layout the decoder trainer reads:
#   OUT/train/<id>.jpg      training images
#   OUT/heldout/<id>.jpg    held-out images for validation (every Kth image of the chosen subset)
# The subset is deterministic: the archive's images in name order, N of them evenly spaced.
#
# Usage: bash datasets_scripts/download_coco.sh [--split val|train] [--count N] [--heldout_every K] [OUT_DIR]
#   --split val     val2017.zip, 5000 images, about 780 MB (default)
#   --split train   train2017.zip, 118287 images, about 18 GB
#   --count N       images to keep (default: all of the split)
#   --heldout_every K   every Kth kept image goes to heldout/ (default 10)
#   OUT_DIR         default data/coco
# Source: https://cocodataset.org/#download (images.cocodataset.org/zips/). The images keep their Flickr
# licences; the archives' MD5 sums below are the published ones.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/lib_download.sh"

split="val"
count=0
heldout_every=10
out_dir=""
while [ $# -gt 0 ]; do
  case "$1" in
    --split) split="${2:?--split needs val or train}"; shift 2 ;;
    --count) count="${2:?--count needs a number}"; shift 2 ;;
    --heldout_every) heldout_every="${2:?--heldout_every needs a number}"; shift 2 ;;
    -h|--help) sed -n '2,17p' "$0"; exit 0 ;;
    -*) die "unknown option $1" ;;
    *) out_dir="$1"; shift ;;
  esac
done
out_dir="${out_dir:-data/coco}"
[[ "$count" =~ ^[0-9]+$ ]] || die "--count must be a non-negative integer, got '$count'"
if ! [[ "$heldout_every" =~ ^[0-9]+$ ]] || [ "$heldout_every" -lt 2 ]; then
  die "--heldout_every must be an integer >= 2, got '$heldout_every'"
fi
case "$split" in
  val) md5=442b8da7639aecaf257c1dceb8ba8c80 ;;
  train) md5=cced6f7f71b7629ddf16f17bbcfab6b2 ;;
  *) die "--split must be val or train, got '$split'" ;;
esac

require_tools unzip md5sum awk
cache="${WATERGS_DOWNLOAD_CACHE:-$out_dir/.downloads}"
zip="$cache/${split}2017.zip"
fetch "http://images.cocodataset.org/zips/${split}2017.zip" "$zip" "$md5"

mapfile -t all_entries < <(unzip -Z1 "$zip" | grep -i '\.jpg$' | LC_ALL=C sort)
total=${#all_entries[@]}
[ "$total" -gt 0 ] || die "$zip holds no JPEG images"
if [ "$count" -eq 0 ] || [ "$count" -gt "$total" ]; then count=$total; fi
# Evenly spaced subset: entry floor(i * total / count) for i = 0..count-1.
mapfile -t chosen < <(printf '%s\n' "${all_entries[@]}" | awk -v n="$count" -v t="$total" \
  'BEGIN { i = 0 } { if (NR - 1 == int(i * t / n) && i < n) { print; i++ } }')

scratch="$(mktemp -d "${out_dir%/}.unpacking.XXXXXX")"
trap 'rm -rf "$scratch"' EXIT
log "extracting ${#chosen[@]} of $total images"
printf '%s\n' "${chosen[@]}" | xargs -d '\n' -n 500 unzip -q -o -j "$zip" -d "$scratch/all" \
  || die "cannot extract images from $zip"
mkdir -p "$scratch/train" "$scratch/heldout"
for i in "${!chosen[@]}"; do
  name="$(basename "${chosen[$i]}")"
  if [ $((i % heldout_every)) -eq $((heldout_every - 1)) ]; then
    mv "$scratch/all/$name" "$scratch/heldout/"
  else
    mv "$scratch/all/$name" "$scratch/train/"
  fi
done
rm -rf "$out_dir/train" "$out_dir/heldout"
mkdir -p "$out_dir"
mv "$scratch/train" "$scratch/heldout" "$out_dir/"
log "done: $(count_images "$out_dir/train") training and $(count_images "$out_dir/heldout") held-out images" \
  "in $out_dir; remove $cache to free the archive's space"
