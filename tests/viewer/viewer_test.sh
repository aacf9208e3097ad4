#!/usr/bin/env bash
# The real web viewer harness (tests/viewer/render.mjs) on a small model of the demo scene
# (120x90, a short training): three.js + @mkkellogg/gaussian-splats-3d and the PlayCanvas engine in
# headless Chromium render the 6 held-out cameras that `watergs render` writes (cameras.json), and
# each screenshot must be well-formed (a PNG of the camera's size, not flat, settled: the same
# over two more draws, no page error, every splat of the file loaded) and the 6 must match
# watergs' renders of the same cameras above MIN_PSNR dB on average. The same cameras with a wrong
# convention (the world-to-camera rotation given where the camera-to-world one is due) must fall
# below it: the floor separates a right conversion from a wrong one. Both on a white background:
# a model this short keeps the large pale splats of its initialisation, which the viewers cut at
# the frame's edges (gaussian-splats-3d drops every splat centred outside 1.2x the frame,
# results/viewers) and which on black leave dark holes watergs' rasteriser does not (black: about
# 15 dB on average, single cameras down to 7.5; white: the values below).
# The floor, measured at commits cf27119 and e57d767 (2-core AMD EPYC, shared; 500 iterations at
# downscale 4, 120x90): the right cameras read 25.8 dB on average with gaussian-splats-3d and 24.2
# with PlayCanvas (single cameras 15.2-30.4: one camera has a splat across it that the viewers draw
# differently), the transposed rotation 9.2 and the camera looking backwards (no y/z flip) 7.3:
# MIN_PSNR 16 sits between them, 6.8 dB above the nearest wrong one and 8.2 below the right ones.
# (The demo's trained model reads 24.2-25.9 dB on black, results/viewers.) Then a short screen
# recording through ffmpeg (below). KEEP_OUT=1 keeps the
# work folder. Skips (exit 77) only where Chromium, node or the harness's node_modules are absent
# (`bash scripts/install_deps.sh --tests` installs them).
set -euo pipefail
bin="${WATERGS_BIN:?WATERGS_BIN: the watergs CLI}"
root="$(cd "$(dirname "$0")/../.." && pwd)"
harness="$root/tests/viewer"
scene="$root/datasets_scripts/demo_scene"
chromium="${CHROMIUM:-/usr/bin/chromium}"
MIN_PSNR="${MIN_PSNR:-16}"
skip() { echo "viewer_test: SKIP: $* (bash scripts/install_deps.sh --tests installs it)"; exit 77; }
fail() { echo "viewer_test: FAIL: $*" >&2; exit 1; }
[ -x "$chromium" ] || skip "no Chromium at $chromium"
command -v node > /dev/null || skip "no node"
command -v ffmpeg > /dev/null || skip "no ffmpeg"
for package in three @mkkellogg/gaussian-splats-3d playcanvas puppeteer-core; do
  [ -f "$harness/node_modules/$package/package.json" ] || skip "no $package in $harness/node_modules"
done
python=/usr/bin/python3
"$python" -c 'import numpy' 2> /dev/null || python=python3
out="$(mktemp -d)"
if [ -n "${KEEP_OUT:-}" ]; then echo "viewer_test: work folder $out (kept)"; else trap 'rm -rf "$out"' EXIT; fi

common=(--workspace_path "$scene" --downscale 4)
"$bin" train "${common[@]}" --output_path "$out/train" --iterations 500 --seed 1 > "$out/train.log" 2>&1 ||
  { tail -n 20 "$out/train.log"; fail "train"; }
model="$out/train/point_cloud.ply"
"$bin" render --input_path "$model" "${common[@]}" --split test --background white --output_path "$out/watergs" \
  > "$out/render.log" 2>&1 ||
  { cat "$out/render.log"; fail "render"; }
[ -f "$out/watergs/cameras.json" ] || fail "watergs render wrote no cameras.json"
count="$("$bin" ply_info --input_path "$model" | awk '/^Gaussians:/ {print $2}')"

# CAMERAS VIEWER NAME: screenshots, checks, and the mean PSNR against watergs' renders on stdout.
shoot() {
  local cameras=$1 viewer=$2 name=$3
  node "$harness/render.mjs" --viewer "$viewer" --model "$model" --cameras "$cameras" \
    --output "$out/$name" --background white > "$out/$name.log" 2>&1 || { cat "$out/$name.log" >&2; fail "render.mjs --viewer $viewer"; }
  "$python" "$harness/compare.py" "$out/watergs" "$out/$name" --json "$out/$name.json" > "$out/$name.txt" ||
    { cat "$out/$name.txt" >&2; fail "compare.py on $name"; }
  "$python" - "$harness" "$out/$name" "$out/$name.json" "$cameras" "$count" "$viewer" <<'PY' || exit 1
import json, os, sys
harness, shots, scores, cameras, count, viewer = sys.argv[1:]
sys.path.insert(0, harness)
from compare import read_png
cams = json.load(open(cameras))
report = json.load(open(os.path.join(shots, "viewer.json")))
problems = []
if report["page_errors"]:
    problems.append(f"page errors: {report['page_errors']}")
loaded = report["splats"]
# gaussian-splats-3d drops splats under 1/255 opacity on load; PlayCanvas keeps every one.
expected_low = int(count) if viewer == "playcanvas" else 0.9 * int(count)
if loaded is None or not (expected_low <= loaded <= int(count)):
    problems.append(f"{loaded} splats loaded of the file's {count}")
for cam, frame in zip(cams, report["frames"]):
    image = read_png(os.path.join(shots, cam["img_name"] + ".png"))
    if image.shape != (cam["height"], cam["width"], 3):
        problems.append(f"{cam['img_name']}: {image.shape[1]}x{image.shape[0]}, camera {cam['width']}x{cam['height']}")
    if image.std() < 5:
        problems.append(f"{cam['img_name']}: flat (std {image.std():.1f})")
    if not frame["settled"]:
        problems.append(f"{cam['img_name']}: still changing after {frame['draws']} draws")
if len(report["frames"]) != len(cams):
    problems.append(f"{len(report['frames'])} frames for {len(cams)} cameras")
for p in problems:
    print(f"viewer_test: {viewer}: {p}", file=sys.stderr)
if problems:
    sys.exit(1)
j = json.load(open(scores))
print("%.2f %.2f" % (j["mean_psnr"], min(r["psnr"] for r in j["images"])))
PY
}

for viewer in gs3d playcanvas; do
  scores="$(shoot "$out/watergs/cameras.json" "$viewer" "$viewer")" || fail "$viewer screenshots"
  read -r mean lowest <<< "$scores"
  echo "viewer_test: $viewer: mean PSNR $mean dB against watergs' renders (lowest camera $lowest dB)"
  awk -v m="$mean" -v f="$MIN_PSNR" 'BEGIN { exit !(m >= f) }' ||
    { cat "$out/$viewer.txt"; fail "$viewer: screenshots do not match watergs' renders (mean $mean dB < $MIN_PSNR)"; }
done

# The control: the rotation transposed (world-to-camera for camera-to-world) must read below the floor.
"$python" - "$out/watergs/cameras.json" "$out/transposed_cameras.json" <<'PY'
import json, sys
cams = json.load(open(sys.argv[1]))
json.dump([dict(c, rotation=[list(r) for r in zip(*c["rotation"])]) for c in cams], open(sys.argv[2], "w"))
PY
scores="$(shoot "$out/transposed_cameras.json" gs3d transposed)" || fail "transposed screenshots"
read -r mean lowest <<< "$scores"
echo "viewer_test: control, rotation transposed: mean PSNR $mean dB (must be < $MIN_PSNR)"
awk -v m="$mean" -v f="$MIN_PSNR" 'BEGIN { exit !(m < f) }' ||
  fail "a wrong camera convention reads $mean dB >= $MIN_PSNR: the floor no longer tells a right conversion from a wrong one"

# A screen recording (issue 54): a fly-through from the first held-out camera to the second
# (flythrough_cameras.py, 3 frames between them) shot by gaussian-splats-3d, encoded as H.264 by
# ffmpeg (libx264 CRF 23, 4:2:0, as screen recorders write it) and decoded: every frame comes back
# at the camera's size and within RECORDING_PSNR dB of its screenshot (30.1-32.7 dB at 120x90
# here, 30.2 at 240x180 in results/viewers/recording; a frame out of order reads 9.4), the path
# starts and ends at the two cameras (each end matches watergs' render of its camera above
# MIN_PSNR) and moves between them (the middle frame matches neither end's render as well as
# that end does). Seen failing with a frame dropped, one out of order, and the path standing still.
"$python" "$harness/flythrough_cameras.py" "$out/watergs/cameras.json" 0 1 4 "$out/fly.json" ||
  fail "flythrough_cameras.py"
node "$harness/render.mjs" --viewer gs3d --model "$model" --cameras "$out/fly.json" --output "$out/fly" \
  --background white > "$out/fly.log" 2>&1 || { cat "$out/fly.log" >&2; fail "render.mjs on the fly-through"; }
ffmpeg -loglevel error -y -framerate 10 -i "$out/fly/frame_%03d.png" -c:v libx264 -preset medium -crf 23 \
  -pix_fmt yuv420p "$out/fly.mp4" || fail "ffmpeg could not encode the fly-through"
mkdir -p "$out/decoded"
ffmpeg -loglevel error -i "$out/fly.mp4" -start_number 0 "$out/decoded/frame_%03d.png" ||
  fail "ffmpeg could not decode the fly-through"
"$python" - "$harness" "$out" "${RECORDING_PSNR:-24}" "$MIN_PSNR" <<'PY' || fail "screen recording"
import json, os, sys
harness, out, floor, min_psnr = sys.argv[1], sys.argv[2], float(sys.argv[3]), float(sys.argv[4])
sys.path.insert(0, harness)
from compare import read_png
import numpy as np

def psnr(a, b):
    mse = np.mean((a.astype(float) - b.astype(float)) ** 2)
    return 10 * np.log10(255.0 ** 2 / max(mse, 1e-12))

frames = json.load(open(os.path.join(out, "fly.json")))
cams = json.load(open(os.path.join(out, "watergs", "cameras.json")))
decoded = sorted(os.listdir(os.path.join(out, "decoded")))
problems = []
if len(decoded) != len(frames) or len(frames) != 5:
    problems.append(f"{len(decoded)} frames decoded of {len(frames)} shot (5 expected)")
shots = [read_png(os.path.join(out, "fly", f["img_name"] + ".png")) for f in frames]
for f, shot, name in zip(frames, shots, decoded):
    back = read_png(os.path.join(out, "decoded", name))
    if back.shape != shot.shape:
        problems.append(f"{name}: {back.shape} decoded, {shot.shape} shot")
    elif psnr(back, shot) < floor:
        problems.append(f"{name}: {psnr(back, shot):.2f} dB from its screenshot after H.264 (< {floor})")
ends = [read_png(os.path.join(out, "watergs", cams[k]["img_name"] + ".png")) for k in (0, 1)]
start, end, middle = psnr(shots[0], ends[0]), psnr(shots[-1], ends[1]), shots[len(shots) // 2]
print(f"viewer_test: recording: {len(decoded)} frames, H.264 {os.path.getsize(os.path.join(out, 'fly.mp4'))} bytes; "
      f"ends {start:.2f} / {end:.2f} dB to their cameras' renders, middle {psnr(middle, ends[0]):.2f} / "
      f"{psnr(middle, ends[1]):.2f}")
if min(start, end) < min_psnr:
    problems.append(f"the path's ends read {start:.2f} / {end:.2f} dB against their cameras (< {min_psnr})")
if psnr(middle, ends[0]) >= start or psnr(middle, ends[1]) >= end:
    problems.append("the middle frame matches an end camera as well as that end does: the path does not move")
for p in problems:
    print(f"viewer_test: recording: {p}", file=sys.stderr)
sys.exit(1 if problems else 0)
PY
echo "viewer_test: PASS"
