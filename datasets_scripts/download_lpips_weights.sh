#!/usr/bin/env bash
# Downloads the VGG-LPIPS weights and converts them to the flat binary `watergs eval` reads:
#   OUT_DIR/lpips_vgg.bin     "watergs LPIPS-VGG weights v1" (format in convert_lpips_weights.py), ~59 MB
#   OUT_DIR/.downloads/       the PyTorch originals:
#     vgg16-397923af.pth      torchvision's ImageNet VGG16, 528 MB (only its 13 conv layers are kept)
#     lpips_v0.1_vgg.pth      LPIPS v0.1 linear heads, a few KB
# PyTorch checkpoints are pickles plus raw storages, which a C++ program cannot read without libtorch;
# the converter (Python standard library only) writes named float32 tensors in C order with a CRC-32.
#
# Usage: bash datasets_scripts/download_lpips_weights.sh [OUT_DIR (default data/lpips)]
# Sources: https://download.pytorch.org/models/vgg16-397923af.pth (the 8 hex digits are the start of its
# SHA-256, checked here) and https://github.com/richzhang/PerceptualSimilarity (lpips/weights/v0.1/vgg.pth).
set -euo pipefail
script_dir="$(dirname "${BASH_SOURCE[0]}")"
source "$script_dir/lib_download.sh"

out_dir="${1:-data/lpips}"
readonly vgg_url="https://download.pytorch.org/models/vgg16-397923af.pth"
readonly lin_url="https://raw.githubusercontent.com/richzhang/PerceptualSimilarity/master/lpips/weights/v0.1/vgg.pth"

require_tools python3 sha256sum md5sum
cache="${WATERGS_DOWNLOAD_CACHE:-$out_dir/.downloads}"
fetch "$vgg_url" "$cache/vgg16-397923af.pth"
sha="$(sha256sum "$cache/vgg16-397923af.pth" | cut -c1-8)"
if [ "$sha" != "397923af" ]; then
  rm -f "$cache/vgg16-397923af.pth"
  die "vgg16-397923af.pth has SHA-256 starting $sha, expected 397923af (removed; run again)"
fi
fetch "$lin_url" "$cache/lpips_v0.1_vgg.pth"

mkdir -p "$out_dir"
python3 "$script_dir/convert_lpips_weights.py" "$cache/vgg16-397923af.pth" "$cache/lpips_v0.1_vgg.pth" \
  "$out_dir/lpips_vgg.bin"
log "done: $out_dir/lpips_vgg.bin (pass it to watergs eval; the .pth originals stay in $cache)"
