#!/usr/bin/env bash
# Issue 54 item 2's curve, simulated: each file rendered at 48 free viewpoints (extract --num_views 48
# --seed 0) under watergs', gaussian-splats-3d's (web) and PlayCanvas' conventions, each render
# through JPEG 90, read as the owner (the raw model's render under the same conventions and JPEG as
# the reference). No browser, no registration: the screenshot as the viewer would draw it.
#   B=BINARY O=OUT bash curve.sh LABEL:RAW:WM:WORKSPACE ...
set -u
cd "$(dirname "$0")/../../.."
B=${B:?binary} O=${O:?output folder}
mkdir -p "$O"
tsv=$O/curve.tsv
[ -f "$tsv" ] || printf 'file\tconventions\t48 free viewpoints: single-view BER (owner, JPEG 90)\n' > "$tsv"
for spec in "$@"; do
  IFS=: read -r label raw wm scene <<< "$spec"
  for c in watergs web playcanvas; do
    grep -q "^$label	$c	" "$tsv" && continue
    line=$("$B" extract --input_path "$wm" --raw_path "$raw" --workspace_path "$scene" --downscale 2 \
      --message text:WGS-26 --num_views 48 --seed 0 --render_conventions $c --image_attack jpeg:90 2>&1 |
      grep "owner's reading): single views")
    printf '%s\t%s\t%s\n' "$label" "$c" "${line#*: }" >> "$tsv"
  done
done
cat "$tsv"
