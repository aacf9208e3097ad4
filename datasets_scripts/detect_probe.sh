#!/usr/bin/env bash
# Screenshots without a pose, read as the owner (docs/history.md, "The owner's reading"): renders a
# watermarked model from 20 free viewpoints as JPEG 90 files (10 whole, 5 cropped to the centred
# 80%, 5 shrunk to 75%), then runs `watergs detect --raw_path RAW --workspace_path WS` on each
# file alone: each image is registered to the workspace, the raw model rendered there, and the bits
# read from the difference. The raw model's own renders from the same viewpoints are the control.
# Appends one line to OUT/results.txt: images read "present" alone, blind and as the owner.
#   datasets_scripts/detect_probe.sh OUT RAW WM [KEY]
# Environment: WATERGS_BIN, SCENE (the demo scene), DECODER, DOWNSCALE (2), WIDTH (240, the
# camera width at DOWNSCALE), MESSAGE (text:WGS-26), DETECT_ARGS (more detect options, e.g.
# "--index_renders 0").
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
out=${1:?usage: detect_probe.sh OUT RAW WM [KEY]}; raw=${2:?RAW}; wm=${3:?WM}; key=${4:-}
bin="${WATERGS_BIN:-$root/build/plugin/watergs}"
scene="${SCENE:-$root/datasets_scripts/demo_scene}"
decoder="${DECODER:-$root/watermark/models/decoder_48_residual_pool2.bin}"
ds="${DOWNSCALE:-2}"; msg="${MESSAGE:-text:WGS-26}"
# The renders' width at that downscale: every file is decoded back at that scale (detect --decode_width).
width="${WIDTH:-240}"
keyed=(); [ -z "$key" ] || keyed=(--key "$key")
read -r -a detect_args <<< "${DETECT_ARGS:-}"
for model in wm raw; do
  ply=$wm; [ "$model" = raw ] && ply=$raw
  dir="$out/shots_$model"; mkdir -p "$dir"
  common=(--input_path "$ply" --workspace_path "$scene" --downscale "$ds" --jpeg_quality 90)
  "$bin" render "${common[@]}" --output_path "$dir/whole" --num_views 10 --seed 5 > /dev/null 2>&1
  "$bin" render "${common[@]}" --output_path "$dir/crop" --num_views 5 --seed 6 --image_attack crop:0.8 > /dev/null 2>&1
  "$bin" render "${common[@]}" --output_path "$dir/small" --num_views 5 --seed 7 --image_attack resize:0.75 > /dev/null 2>&1
  "$bin" detect --image_path "$dir/whole,$dir/crop,$dir/small" --decoder "$decoder" --message "$msg" \
    "${keyed[@]}" --decode_width "$width" --raw_path "$raw" --workspace_path "$scene" --downscale "$ds" \
    --json "$dir/detect.json" "${detect_args[@]}" > "$dir/detect.txt"
done
/usr/bin/python3 - "$out" "$key" <<'PY'
import json, sys
out, key = sys.argv[1:]
def count(model):
    j = json.load(open(f"{out}/shots_{model}/detect.json"))
    blind = sum(v.get("verdict") == "watermark present" for v in j["views"])
    o = j["owner"]
    reg = sum(r["registered"] for r in o["registrations"])
    owner = sum(v.get("bit_errors", 99) <= 7 for v in o.get("views", []))  # 1e-6: at most 7 of 48 wrong
    errs = sorted(v["bit_errors"] for v in o.get("views", []))
    return blind, reg, owner, errs, len(j["views"])
w, r = count("wm"), count("raw")
line = (f"wm: {w[2]} of {w[4]} present alone as the owner ({w[1]} registered; bit errors {w[3]}), "
        f"{w[0]} blind | raw control: {r[2]} present as the owner ({r[1]} registered), {r[0]} blind"
        f"{' | keyed' if key else ''}")
print(line)
open(f"{out}/results.txt", "a").write(line + "\n")
# Registration against the truth: render writes each viewpoint's camera (cameras.json); the camera
# centre each registration found, off by a fraction of the spread of the 20 true centres.
import math, os
truth = {}
for sub in ("whole", "crop", "small"):
    path = f"{out}/shots_wm/{sub}/cameras.json"
    if os.path.exists(path):
        for c in json.load(open(path)):
            truth[f"{sub}/{c['img_name']}"] = c["position"]
if truth:
    centres = list(truth.values())
    mean = [sum(c[a] for c in centres) / len(centres) for a in range(3)]
    spread = max(math.dist(c, mean) for c in centres) or 1
    o = json.load(open(f"{out}/shots_wm/detect.json"))["owner"]
    errs = {v["name"]: v["bit_errors"] for v in o.get("views", [])}
    items = []
    for r in o["registrations"]:
        key = "/".join(r["name"].split("/")[-2:]).rsplit(".", 1)[0]
        if r.get("registered") and key in truth:
            off = math.dist(r["camera"]["center"], truth[key]) / spread
            items.append(f"{key} {off:.3f} ({errs.get(r['name'], '?')} wrong)")
    line = "registration centre error / spread: " + ", ".join(items)
    print(line)
    open(f"{out}/results.txt", "a").write(line + "\n")
PY
