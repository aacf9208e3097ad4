#!/usr/bin/env bash
# Issue 54 item 3: a screen recording of a real web viewer, read as the owner. A fly-through of the
# demo's orbit from camera FIRST to LAST (STEPS - 1 frames between neighbours, tests/viewer/flythrough_cameras.py)
# is rendered frame by frame by the viewer in headless Chromium (tests/viewer/render.mjs, its
# defaults), encoded as H.264 by ffmpeg (libx264, CRF 23 = its default rate control, preset medium,
# 4:2:0, FPS frames a second), decoded back to PNG frames and read by
# `watergs detect --raw_path RAW --workspace_path WS --downscale 2` (defaults: the reference's
# conventions chosen per frame). The raw model's recording along the same path is the control.
#   results/viewers/recording/measure.sh RAW WM OUT
# Environment: WATERGS_BIN, VIEWER (gs3d | playcanvas; gs3d), FIRST (0), LAST (8), STEPS (4),
# FPS (10), CRF (23), DECODER (detect's decoder: the one the file was embedded for). Writes OUT/<viewer>_<model>.mp4 (+ .probe.json: ffprobe's bitrate),
# OUT/detect_<viewer>_<model>.{txt,json,time} and OUT/recording.tsv: per model, frames registered,
# bits wrong per frame, verdicts alone, all frames together, and how many frames from the start
# the aggregate (mean logits) needs to read "present".
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../../.." && pwd)"
raw=${1:?usage: measure.sh RAW WM OUT}; wm=${2:?WM}; out=${3:?OUT}
bin="${WATERGS_BIN:-$root/build/plugin/watergs}"
scene="${SCENE:-$root/datasets_scripts/demo_scene}"
viewer="${VIEWER:-gs3d}" fps="${FPS:-10}" crf="${CRF:-23}"
message="text:WGS-26"
mkdir -p "$out"
[ -f "$out/all/cameras.json" ] || "$bin" render --input_path "$raw" --workspace_path "$scene" --downscale 2 \
  --split all --output_path "$out/all" > "$out/all.log" 2>&1
/usr/bin/python3 "$root/tests/viewer/flythrough_cameras.py" "$out/all/cameras.json" "${FIRST:-0}" "${LAST:-8}" "${STEPS:-4}" \
  "$out/flythrough.json"
for model in wm raw; do
  ply="$wm"; [ "$model" = raw ] && ply="$raw"
  name="${viewer}_$model" frames="$out/frames_${viewer}_$model" decoded="$out/decoded_${viewer}_$model"
  [ -f "$frames/viewer.json" ] || node "$root/tests/viewer/render.mjs" --viewer "$viewer" --model "$ply" \
    --cameras "$out/flythrough.json" --output "$frames" > "$frames.log" 2>&1
  if [ ! -f "$out/$name.mp4" ]; then
    ffmpeg -loglevel error -y -framerate "$fps" -i "$frames/frame_%03d.png" -c:v libx264 -preset medium \
      -crf "$crf" -pix_fmt yuv420p "$out/$name.tmp.mp4"
    mv "$out/$name.tmp.mp4" "$out/$name.mp4"
  fi
  ffprobe -loglevel error -show_entries format=bit_rate,duration:stream=codec_name,width,height,nb_frames \
    -of json "$out/$name.mp4" > "$out/$name.probe.json"
  rm -rf "$decoded"; mkdir -p "$decoded"
  ffmpeg -loglevel error -i "$out/$name.mp4" -start_number 0 "$decoded/frame_%03d.png"
  if [ ! -f "$out/detect_$name.json" ]; then
    start=$SECONDS
    "$bin" detect --image_path "$decoded" --message "$message" --raw_path "$raw" --workspace_path "$scene" ${DECODER:+--decoder "$DECODER"} \
      --downscale 2 --json "$out/detect_$name.json.tmp" > "$out/detect_$name.txt" 2>&1
    mv "$out/detect_$name.json.tmp" "$out/detect_$name.json"
    echo "$((SECONDS - start)) s for $(ls "$decoded" | wc -l) frames" > "$out/detect_$name.time"
  fi
done
/usr/bin/python3 - "$out" "$viewer" <<'PY'
import json, math, sys
out, viewer = sys.argv[1], sys.argv[2]

def p_value(errors, bits=48):  # detect's: chance of this many matching bits by luck
    return sum(math.comb(bits, k) for k in range(bits - errors, bits + 1)) / 2 ** bits

def verdict(errors):
    p = p_value(errors)
    return "present" if p <= 1e-6 else ("absent" if p > 0.01 else "inconclusive")

rows = ["recording\tbitrate (kbit/s)\tframes registered\tbits wrong of 48 per frame\tmean BER"
        "\tpresent / inconclusive / absent alone\tall frames together\tframes needed (from the start)"
        "\treferences chosen\tdetect's time"]
for model in ("wm", "raw"):
    name = f"{viewer}_{model}"
    j = json.load(open(f"{out}/detect_{name}.json"))
    probe = json.load(open(f"{out}/{name}.probe.json"))
    owner = j["owner"]
    expected = [c == "1" for c in owner["expected_bits"]]
    views = sorted(owner.get("views", []), key=lambda v: v["name"])
    errors = [v["bit_errors"] for v in views]
    alone = [verdict(e) for e in errors]
    counts = " / ".join(str(alone.count(w)) for w in ("present", "inconclusive", "absent"))
    needed, together = "never", None
    for k in range(1, len(views) + 1):
        mean = [sum(v["logits"][i] for v in views[:k]) / k for i in range(48)]
        wrong = sum((m > 0) != e for m, e in zip(mean, expected))
        if needed == "never" and verdict(wrong) == "present":
            needed = str(k)
        together = wrong
    refs = [r["reference"]["conventions"] for r in owner["registrations"] if r["registered"]]
    chosen = ", ".join(f"{c} {refs.count(c)}" for c in sorted(set(refs)))
    registered = sum(r["registered"] for r in owner["registrations"])
    rows.append(f"{name}\t{int(probe['format']['bit_rate']) / 1000:.0f}\t{registered} of {len(owner['registrations'])}"
                f"\t{', '.join(map(str, errors))}\t{100 * sum(errors) / (48 * max(len(errors), 1)):.1f}%"
                f"\t{counts}\t{verdict(together) if together is not None else '-'} ({together} of 48)"
                f"\t{needed}\t{chosen}\t{open(f'{out}/detect_{name}.time').read().strip()}")
open(f"{out}/recording.tsv", "w").write("\n".join(rows) + "\n")
PY
cat "$out/recording.tsv"
