#!/usr/bin/env bash
# `watergs reconstruct` on photos in no capture order: 24 of the demo's photos (half the circle,
# both heights, 15 degrees apart) under random names (hashes of their names), with
# --sequential_above 20 so that named in order they would have been matched sequentially. The plan
# must see no order, match every pair and give each photo its own camera (photos of a web
# collection come from many cameras); the model must register all 24 and place them where they
# were taken (the POV-Ray cameras, renamed the same way). Half the photos make a quarter of the
# pairs (26 s instead of ~2 min). Not any half: one ring at one height (view_000-023) or every
# second photo (30 degrees apart) registered 24 of 24 at 0.3 px in a collapsed model (centres 100%
# off, scale 0.0008-0.04), with a camera per photo and with one camera for all alike.
set -euo pipefail
bin="${WATERGS_BIN:?WATERGS_BIN: the watergs CLI}"
root="$(cd "$(dirname "$0")/../.." && pwd)"
command -v colmap > /dev/null || { echo "unordered_photos_test: colmap not installed (scripts/install_deps.sh --tests)"; exit 77; }
out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT
fail() { echo "unordered_photos_test: FAIL: $*" >&2; exit 1; }

mkdir -p "$out/photos" "$out/truth"
cp "$root/datasets_scripts/demo_scene/ground_truth/"* "$out/truth/"
for photo in "$root"/datasets_scripts/demo_scene/images/view_0{00..11}.jpg "$root"/datasets_scripts/demo_scene/images/view_0{24..35}.jpg; do
  name=$(basename "$photo")
  hashed="$(printf '%s' "$name" | sha256sum | cut -c1-10).jpg"
  cp "$photo" "$out/photos/$hashed"
  sed -i "s/ $name\$/ $hashed/" "$out/truth/images.txt"
done
[ "$(ls "$out/photos" | wc -l)" -eq 24 ] || fail "renaming lost photos"

"$bin" reconstruct --image_path "$out/photos" --workspace_path "$out/ws" --sequential_above 20 \
  > "$out/run.log" 2> "$out/run.err" || fail "reconstruct: $(tail -3 "$out/run.log" "$out/run.err")"
cat "$out/run.log"
grep -q "matcher exhaustive: 24 photos, 276 pairs (names in no capture order" "$out/run.log" ||
  fail "not matched every pair as photos in no order"
grep -q "a camera per photo" "$out/run.log" || fail "photos in no order share a camera"
grep -q "24 of 24 photos registered" "$out/run.log" || fail "not every photo registered"
"$bin" model_info --sparse_path "$out/ws" > "$out/info.log"
grep -q "^Cameras: 24$" "$out/info.log" || fail "not a camera per photo: $(grep Cameras "$out/info.log")"
"$bin" model_info --sparse_path "$out/ws" --reference_path "$out/truth" > "$out/poses.log" ||
  fail "model_info: $(cat "$out/poses.log")"
poses=$(grep "Poses against the reference" "$out/poses.log") || fail "no pose comparison"
echo "$poses"
echo "$poses" | grep -q "24 common images" || fail "not 24 common images"
worst=$(echo "$poses" | sed -E 's/.*at most ([0-9.]+)% .*/\1/')
awk -v w="$worst" 'BEGIN { exit !(w < 2.0) }' || fail "a camera $worst% of the capture's size from where it was taken"
echo "unordered_photos_test: passed"
