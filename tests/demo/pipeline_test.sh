#!/usr/bin/env bash
# `watergs pipeline` on the demo scene's photos, short: reconstruct (kept from the shared
# fixture under CTest), train, embed with the
# report; the report's claim reads "present" with the owner's key; a second run keeps every
# stage; bad input fails in one line before anything runs.
set -euo pipefail
bin="${WATERGS_BIN:?WATERGS_BIN: the watergs CLI}"
root="$(cd "$(dirname "$0")/../.." && pwd)"
photos="$root/datasets_scripts/demo_scene/images"
decoder="$root/watermark/models/decoder_48.bin"
command -v colmap > /dev/null || { echo "pipeline_test: colmap not installed (scripts/install_deps.sh)"; exit 77; }
out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT
fail() { echo "pipeline_test: FAIL: $*" >&2; exit 1; }
printf 'pipeline test key\n' > "$out/owner.key"
run=(--image_path "$photos" --decoder "$decoder" --message text:PIPE-1 --key "file:$out/owner.key"
  --output_path "$out/result" --downscale 4 --iterations 1500
)
# The reconstruct stage starts from the demo_reconstruction fixture's workspace (shared with
# reconstruct_test; the same command and settings as this pipeline's stage), so it is kept at
# once; without the fixture the pipeline reconstructs.
if [ -n "${WATERGS_DEMO_RECONSTRUCTION:-}" ]; then
  [ -d "$WATERGS_DEMO_RECONSTRUCTION/ws" ] || fail "no reconstruction in $WATERGS_DEMO_RECONSTRUCTION"
  mkdir -p "$out/result"
  cp -a "$WATERGS_DEMO_RECONSTRUCTION/ws" "$out/result/workspace"
fi
"$bin" pipeline "${run[@]}" > "$out/run1.log" 2>&1 || fail "pipeline: $(tail -5 "$out/run1.log")"
for f in workspace/sparse/0/images.bin train/point_cloud.ply watermarked.ply report.html; do
  [ -f "$out/result/$f" ] || fail "no $f"
done
grep -q 'class="verdict">watermark present<' "$out/result/report.html" || fail "the report's claim is not present"
grep -q "$(printf 'pipeline test key' | sha256sum | cut -c1-64)" "$out/result/report.html" || fail "no key fingerprint in the report"
"$bin" pipeline "${run[@]}" > "$out/run2.log" 2>&1 || fail "second run: $(tail -3 "$out/run2.log")"
[ "$(grep -c "done before, kept" "$out/run2.log")" -eq 3 ] || fail "stages redone: $(cat "$out/run2.log")"
if "$bin" pipeline "${run[@]/$photos/$out/none}" > "$out/err.log" 2>&1; then fail "accepted a missing folder"; fi
grep -q "$out/none" "$out/err.log" || fail "error does not name the folder: $(cat "$out/err.log")"
[ "$(wc -l < "$out/err.log")" -le 1 ] || fail "more than one line: $(cat "$out/err.log")"
echo "pipeline_test: passed ($(grep -c . "$out/run1.log") lines of output)"
