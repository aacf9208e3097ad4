#!/usr/bin/env bash
# Issue 54 item 2, the reading side: the same JPEG-90 screenshots of real web viewers read as the
# owner with the reference rendered as watergs renders (`--reference_conventions watergs`, what
# detect did before) and chosen per image among the registry's conventions
# (`--reference_conventions auto`, the default).
#   results/viewers/reference_conventions/measure.sh RAW WM OUT
# RAW: the raw demo model; WM: its watermark (embed's defaults). Screenshots as
# results/viewers/measure_ber.sh takes them (tests/viewer/render.mjs, each viewer's defaults, the 6
# held-out cameras at 240x180, JPEG 90 by ImageMagick with 4:2:0): OUT/shots_<viewer>_<model>/,
# OUT/jpeg_<viewer>_<model>/. Each setting reads all of them in one detect call (the index is built
# by the first and read from the workspace's cache by the second): OUT/detect_<setting>.{txt,json,
# time}. OUT/ber.tsv: per setting and screenshot set, bits wrong per image, mean BER, verdicts
# alone, the set together, the reference chosen and its PSNR to the screenshot. OUT/gap.tsv: the
# screenshots' PSNR against watergs' render of the same model under each named conventions.
# SHOTS_ONLY=1: stop there (no detect). FREE_VIEWS=N: N free viewpoints between the cameras (render
# --num_views N --seed 0) instead of the held-out cameras. SCENE: another workspace (read at
# --downscale 2 like the demo), e.g. fern's. SETTINGS: the detect settings to run ("watergs auto").
# DECODER: the decoder detect reads with (default: detect's), for a file embedded with another.
set -euo pipefail
root="$(cd "$(dirname "$0")/../../.." && pwd)"
raw=${1:?usage: measure.sh RAW WM OUT}; wm=${2:?WM}; out=${3:?OUT}
bin="${WATERGS_BIN:-$root/build/plugin/watergs}"
command -v convert > /dev/null ||
  { echo "measure.sh: ImageMagick's convert is missing (apt-get install imagemagick)" >&2; exit 1; }
scene="${SCENE:-$root/datasets_scripts/demo_scene}"
views=(--split test)
[ -n "${FREE_VIEWS:-}" ] && views=(--num_views "$FREE_VIEWS" --seed 0)
message="text:WGS-26"
mkdir -p "$out"
for model in wm raw; do
  ply="$wm"; [ "$model" = raw ] && ply="$raw"
  [ -f "$out/watergs_$model/cameras.json" ] || "$bin" render --input_path "$ply" --workspace_path "$scene" \
    --downscale 2 "${views[@]}" --output_path "$out/watergs_$model" > "$out/watergs_$model.log" 2>&1
done
for viewer in gs3d playcanvas; do
  for model in wm raw; do
    ply="$wm"; [ "$model" = raw ] && ply="$raw"
    shots="$out/shots_${viewer}_$model" jpeg="$out/jpeg_${viewer}_$model"
    [ -f "$shots/viewer.json" ] || node "$root/tests/viewer/render.mjs" --viewer "$viewer" --model "$ply" \
      --cameras "$out/watergs_wm/cameras.json" --output "$shots" > "$shots.log" 2>&1
    mkdir -p "$jpeg"
    for png in "$shots"/*.png; do
      jpg="$jpeg/$(basename "$png" .png).jpg"
      [ -f "$jpg" ] || convert "$png" -quality 90 -sampling-factor 4:2:0 "$jpg"
    done
  done
done
# The renderer gap: each viewer's PNG screenshots against watergs' render under each conventions.
for conventions in watergs web playcanvas; do
  for model in wm raw; do
    ply="$wm"; [ "$model" = raw ] && ply="$raw"
    ref="$out/conventions_${conventions}_$model"
    [ -f "$ref/cameras.json" ] || "$bin" render --input_path "$ply" --workspace_path "$scene" --downscale 2 \
      "${views[@]}" --render_conventions "$conventions" --output_path "$ref" > "$ref.log" 2>&1
    for viewer in gs3d playcanvas; do
      /usr/bin/python3 "$root/tests/viewer/compare.py" "$ref" "$out/shots_${viewer}_$model" \
        --json "$out/gap_${viewer}_${model}_$conventions.json" > "$out/gap_${viewer}_${model}_$conventions.txt"
    done
  done
done
[ -n "${SHOTS_ONLY:-}" ] && exit 0  # the screenshots and the gap only
images="$out/jpeg_gs3d_wm,$out/jpeg_playcanvas_wm,$out/jpeg_gs3d_raw,$out/jpeg_playcanvas_raw"
for setting in ${SETTINGS:-watergs auto}; do
  [ -f "$out/detect_$setting.json" ] && continue
  start=$SECONDS
  nice -n 10 "$bin" detect --image_path "$images" --message "$message" --raw_path "$raw" ${DECODER:+--decoder "$DECODER"} \
    --workspace_path "$scene" --downscale 2 --reference_conventions "$setting" \
    --json "$out/detect_$setting.json.tmp" > "$out/detect_$setting.txt" 2>&1
  mv "$out/detect_$setting.json.tmp" "$out/detect_$setting.json"
  echo "$((SECONDS - start)) s for $(ls "$out"/jpeg_*/*.jpg | wc -l) images" > "$out/detect_$setting.time"
done
/usr/bin/python3 - "$out" <<'PY'
import json, math, os, sys
out = sys.argv[1]

def verdict(errors, bits=48):  # detect's: binomial tail p-value, present <= 1e-6, absent > 0.01
    p = sum(math.comb(bits, k) for k in range(bits - errors, bits + 1)) / 2 ** bits
    return "present" if p <= 1e-6 else ("absent" if p > 0.01 else "inconclusive")

rows = ["setting\tscreenshots\tregistered\tbits wrong of 48 per image\tmean BER"
        "\tpresent / inconclusive / absent alone\ttogether\treference chosen\tits PSNR to the screenshot (dB)"
        "\tPSNR per candidate (dB, mean)\tdetect's time"]
for setting in ("watergs", "auto"):
    path = f"{out}/detect_{setting}.json"
    if not os.path.exists(path):
        continue
    j = json.load(open(path))
    owner = j["owner"]
    expected = [c == "1" for c in owner["expected_bits"]]
    time = open(f"{out}/detect_{setting}.time").read().strip()
    for folder in ("jpeg_gs3d_wm", "jpeg_playcanvas_wm", "jpeg_gs3d_raw", "jpeg_playcanvas_raw"):
        regs = [r for r in owner["registrations"] if f"/{folder}/" in r["name"]]
        views = [v for v in owner.get("views", []) if f"/{folder}/" in v["name"]]
        errors = [v["bit_errors"] for v in views]
        alone = [verdict(e) for e in errors]
        counts = " / ".join(str(alone.count(w)) for w in ("present", "inconclusive", "absent"))
        mean = [sum(v["logits"][i] for v in views) / len(views) for i in range(48)]
        together = sum((m > 0) != e for m, e in zip(mean, expected))
        refs = [r["reference"] for r in regs if r["registered"]]
        chosen = [r["conventions"] for r in refs]
        psnr = [r["psnr"][r["conventions"]] for r in refs]
        names = list(refs[0]["psnr"]) if refs else []
        per = ", ".join(f"{n} {sum(r['psnr'][n] for r in refs) / len(refs):.2f}" for n in names)
        rows.append(f"{setting}\t{folder[5:]}\t{sum(r['registered'] for r in regs)} of {len(regs)}\t"
                    f"{', '.join(map(str, errors))}\t{100 * sum(errors) / (48 * max(len(errors), 1)):.1f}%\t"
                    f"{counts}\t{verdict(together)} ({together} of 48)\t{', '.join(chosen)}\t"
                    f"{', '.join(f'{p:.2f}' for p in psnr)}\t{per}\t{time}")
open(f"{out}/ber.tsv", "w").write("\n".join(rows) + "\n")
gap = ["viewer\tmodel\twatergs renders with\tmean PSNR (dB)\tper camera"]
for viewer in ("gs3d", "playcanvas"):
    for model in ("wm", "raw"):
        for conventions in ("watergs", "web", "playcanvas"):
            path = f"{out}/gap_{viewer}_{model}_{conventions}.json"
            if not os.path.exists(path):
                continue
            j = json.load(open(path))
            per = " ".join(f"{r['psnr']:.2f}" for r in j["images"])
            gap.append(f"{viewer}\t{model}\t{conventions}\t{j['mean_psnr']:.2f}\t{per}")
open(f"{out}/gap.tsv", "w").write("\n".join(gap) + "\n")
PY
cat "$out/ber.tsv"
