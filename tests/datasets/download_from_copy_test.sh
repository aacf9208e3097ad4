#!/usr/bin/env bash
# download_llff.sh --from DIR: a local copy laid out as the same workspace, with photos.sha256 that
# `sha256sum -c` accepts and that catches a changed photo; a copy without images.bin is laid out with a
# warning naming `watergs reconstruct`, and so is a copy of the photos alone; an unknown scene or folder is a one-line error, non-zero exit.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
script="$here/../../datasets_scripts/download_llff.sh"
demo="$here/../../datasets_scripts/demo_scene"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

# A copy as a repository carries it: data/<scene>/{images,sparse/0,poses_bounds.npy}.
mkdir -p "$tmp/copy/data/room/sparse/0" "$tmp/copy/data/trex/sparse/0"
cp -r "$demo/images" "$tmp/copy/data/room/images"
cp "$demo"/sparse/0/*.bin "$tmp/copy/data/room/sparse/0/"
echo "not really numpy" > "$tmp/copy/data/room/poses_bounds.npy"
cp -r "$demo/images" "$tmp/copy/data/trex/images"
cp "$demo/sparse/0/cameras.bin" "$demo/sparse/0/points3D.bin" "$tmp/copy/data/trex/sparse/0/"
mkdir -p "$tmp/copy/data/horns"  # photos and poses_bounds.npy, no model (github Bussler/CustomNeRF)
cp -r "$demo/images" "$tmp/copy/data/horns/images"

bash "$script" --from "$tmp/copy" "$tmp/out" room trex horns 2> "$tmp/log" || { cat "$tmp/log"; fail "--from failed"; }
photos=$(find "$demo/images" -type f | wc -l)
[ "$(grep -c '  images/' "$tmp/out/room/photos.sha256")" -eq "$photos" ] || fail "manifest misses photos"
grep -q '  sparse/0/images.bin$' "$tmp/out/room/photos.sha256" || fail "manifest misses the model"
grep -q '  poses_bounds.npy$' "$tmp/out/room/photos.sha256" || fail "manifest misses poses_bounds.npy"
(cd "$tmp/out/room" && sha256sum -c --quiet photos.sha256) || fail "manifest does not check"
cmp -s "$demo/sparse/0/images.bin" "$tmp/out/room/sparse/0/images.bin" || fail "model not copied"
grep -q "trex/sparse/0 has no images.bin.*watergs reconstruct" "$tmp/log" || fail "no reconstruct warning"
grep -q "ready: $tmp/out/trex" "$tmp/log" || fail "trex not laid out"
grep -q "horns has no COLMAP model.*watergs reconstruct" "$tmp/log" || fail "no model: no reconstruct warning"
grep -q "ready: $tmp/out/horns" "$tmp/log" || fail "horns not laid out"
# A changed photo no longer checks.
first=$(find "$tmp/out/room/images" -type f | sort | head -1)
printf 'x' >> "$first"
if (cd "$tmp/out/room" && sha256sum -c --quiet photos.sha256 > /dev/null 2>&1); then
  fail "a changed photo passed the manifest"
fi
# One-line errors.
if bash "$script" --from "$tmp/copy" "$tmp/out2" fern 2> "$tmp/err"; then fail "missing scene accepted"; fi
grep -q "holds no fern/images" "$tmp/err" || { cat "$tmp/err"; fail "missing scene: no reason"; }
if bash "$script" --from "$tmp/nowhere" "$tmp/out2" room 2> "$tmp/err"; then fail "missing folder accepted"; fi
grep -q "nowhere: no such folder" "$tmp/err" || { cat "$tmp/err"; fail "missing folder: no reason"; }
[ ! -e "$tmp/out2/fern" ] || fail "a failed scene left a folder"
echo "download_from_copy_test: OK"
