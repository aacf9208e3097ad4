#!/usr/bin/env bash
# `watergs reconstruct` on the demo scene's 48 photos with COLMAP's binary: the model registers
# (nearly) every photo at sub-pixel reprojection error, in the right place (camera poses against
# the scene's known ones, up to a similarity: a sub-pixel error alone let through a model that
# joined two groups of photos in a wrong relative pose), `train` accepts the workspace, a second
# run resumes (every stage kept, the same model), and bad input fails in one line naming it.
set -euo pipefail
bin="${WATERGS_BIN:?WATERGS_BIN: the watergs CLI}"
root="$(cd "$(dirname "$0")/../.." && pwd)"
photos="$root/datasets_scripts/demo_scene/images"
command -v colmap > /dev/null || { echo "reconstruct_test: colmap not installed (scripts/install_deps.sh)"; exit 77; }
out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT
fail() { echo "reconstruct_test: FAIL: $*" >&2; exit 1; }
one_line_error() {  # WHAT COMMAND...: non-zero exit, one line naming WHAT
  local what=$1; shift
  if "$@" > "$out/err.log" 2>&1; then fail "accepted: $*"; fi
  grep -q -- "$what" "$out/err.log" || fail "error does not name $what: $(cat "$out/err.log")"
  [ "$(wc -l < "$out/err.log")" -le 1 ] || fail "more than one line: $(cat "$out/err.log")"
}

# The reconstruction: the demo_reconstruction fixture's (WATERGS_DEMO_RECONSTRUCTION, shared with
# pipeline_test), else made here; always a copy, so the resume below also checks that a workspace
# moved elsewhere resumes (its stage markers hold the workspace as $WORKSPACE).
fixture="${WATERGS_DEMO_RECONSTRUCTION:-}"
if [ -z "$fixture" ]; then
  fixture="$out/fixture"
  bash "$root/tests/demo/demo_reconstruction.sh" "$fixture" > /dev/null || fail "reconstruct failed"
fi
[ -d "$fixture/ws" ] || fail "no reconstruction in $fixture (did demo_reconstruction fail?)"
cp -a "$fixture/ws" "$out/ws"
cp "$fixture/run1.log" "$fixture/run1.err" "$out/"
ws="$out/ws"
cat "$out/run1.log"
line=$(grep "photos registered" "$out/run1.log") || fail "no summary line"
registered=$(echo "$line" | sed -E 's/.*: ([0-9]+) of ([0-9]+) photos.*/\1/')
error=$(echo "$line" | sed -E 's/.*reprojection error ([0-9.]+) px.*/\1/')
[ "$registered" -ge 45 ] || fail "only $registered of 48 photos registered"
awk -v e="$error" 'BEGIN { exit !(e > 0 && e < 1.0) }' || fail "mean reprojection error $error px"
[ -f "$ws/sparse/0/images.bin" ] || fail "no sparse/0"
grep -q "matcher exhaustive" "$out/run1.log" || fail "48 photos not matched exhaustively"
# Placed right: every camera centre within 2% of the capture's size of the true one (the POV-Ray
# cameras the photos were rendered from, demo_scene/ground_truth; sparse/0 is itself a mapper run).
"$bin" model_info --sparse_path "$ws" --reference_path "$root/datasets_scripts/demo_scene/ground_truth" \
  > "$out/poses.log" || fail "model_info: $(cat "$out/poses.log")"
poses=$(grep "Poses against the reference" "$out/poses.log") || fail "no pose comparison"
echo "$poses"
worst=$(echo "$poses" | sed -E 's/.*at most ([0-9.]+)% .*/\1/')
awk -v w="$worst" 'BEGIN { exit !(w < 2) }' || fail "photos misplaced: $poses"
[ -L "$ws/images" ] || fail "images/ does not link the photos"
"$bin" train --workspace_path "$ws" --output_path "$out/train" --iterations 30 \
  --downscale 4 --num_threads 2 > "$out/train.log" 2>&1 || fail "train refused the workspace: $(tail -2 "$out/train.log")"
[ -f "$out/train/point_cloud.ply" ] || fail "train wrote no model"

# Resume: every stage (features, matching, verification, mapping) kept, the same model.
sum1=$(md5sum < "$ws/sparse/0/points3D.bin")
"$bin" reconstruct --image_path "$photos" --workspace_path "$ws" \
  > "$out/run2.log" 2>&1 || fail "second run: $(tail -2 "$out/run2.log")"
[ "$(grep -c "done before, kept" "$out/run2.log")" -eq 4 ] || fail "stages redone: $(cat "$out/run2.log")"
[ "$(md5sum < "$ws/sparse/0/points3D.bin")" = "$sum1" ] || fail "the model changed on resume"
grep -q "matching on the CPU: exact" "$out/run1.log" || fail "not matched by watergs on the CPU"
# A workspace matched by COLMAP's own matcher (before watergs matched): its marker covers the
# matching and the verification, and the run resumes with every stage kept.
cp -a "$ws" "$out/ws_colmap_matched"
rm "$out/ws_colmap_matched/.reconstruct/verification.done"
threads=$(sed -nE 's/.*--SiftMatching.num_threads ([0-9]+).*/\1/p' "$ws/.reconstruct/verification.done")
echo "colmap exhaustive_matcher --database_path \$WORKSPACE/database.db --SiftMatching.use_gpu 0" \
  "--SiftMatching.num_threads $threads --ExhaustiveMatching.block_size 10" \
  > "$out/ws_colmap_matched/.reconstruct/matching.done"
"$bin" reconstruct --image_path "$photos" --workspace_path "$out/ws_colmap_matched" \
  > "$out/run3.log" 2>&1 || fail "COLMAP-matched workspace: $(tail -2 "$out/run3.log")"
[ "$(grep -c "done before, kept" "$out/run3.log")" -eq 4 ] || fail "COLMAP-matched stages redone: $(cat "$out/run3.log")"
# Other settings on a started workspace: refused, not mixed.
one_line_error "other settings" "$bin" reconstruct --image_path "$photos" --workspace_path "$ws" \
  --max_features 512

# Bad input.
mkdir -p "$out/two"
cp "$photos/view_000.jpg" "$photos/view_001.jpg" "$out/two/"
one_line_error "$out/two" "$bin" reconstruct --image_path "$out/two" --workspace_path "$out/ws2"
printf 'not a jpeg' > "$out/two/view_002.jpg"
one_line_error "$out/two/view_002.jpg" "$bin" reconstruct --image_path "$out/two" \
  --workspace_path "$out/ws5"
[ ! -e "$out/ws5" ] || fail "a refused run wrote the workspace"
one_line_error "no COLMAP binary" "$bin" reconstruct --image_path "$photos" \
  --workspace_path "$out/ws3" --colmap "$out/no-colmap"
one_line_error "$out/none" "$bin" reconstruct --image_path "$out/none" --workspace_path "$out/ws4"
echo "reconstruct_test: passed ($registered of 48 registered, $error px, centres within $worst%)"
