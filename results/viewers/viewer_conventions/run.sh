#!/usr/bin/env bash
# Issue 54, session 32: the session-31 screenshots (results/viewers/default_t38/*/jpeg_*, the same
# files) read again after the viewers' conventions were completed (gaussian-splats-3d's eigenvalue
# floor and 2.83-sigma cut, PlayCanvas' minimum size and renormalised falloff): the references
# re-rendered, the renderer gap and detect (auto) redone by measure.sh, which skips the screenshots
# it finds. Then the same files read by the simulator (`extract --render_conventions`, JPEG 90, no
# browser) at the held-out cameras.
#   B=BINARY SRC=SESSION31_FOLDER O=OUT \
#   DEMO_RAW=... DEMO_WM=... DEMO_JL=... FERN_WS=... FERN_RAW=... FERN_WM=... FERN_JL=... bash run.sh
# (SRC: the session-31 measurement folders, with shots_*, jpeg_* and watergs_*; the files as
# results/viewers/default_t38/README.md names them.)
set -u
cd "$(dirname "$0")/../../.."
B=${B:?binary} SRC=${SRC:?session-31 folders} O=${O:?output}
demo=datasets_scripts/demo_scene
go() {  # NAME RAW WM SCENE [FREE]
  local name=$1 raw=$2 wm=$3 scene=$4 free=${5:-}
  local out=$O/$name
  [ -f "$out/detect_auto.json" ] && return
  mkdir -p "$out"
  cp -rn "$SRC/$name"/shots_* "$SRC/$name"/jpeg_* "$SRC/$name"/watergs_* "$out/" 2>/dev/null
  SETTINGS=auto SCENE=$scene FREE_VIEWS=$free WATERGS_BIN=$B PATH=/usr/bin:$PATH nice bash \
    results/viewers/reference_conventions/measure.sh "$raw" "$wm" "$out" > "$out.log" 2>&1
}
go fern_t38 "$FERN_RAW" "$FERN_WM" "$FERN_WS"
go fern_t38j "$FERN_RAW" "$FERN_JL" "$FERN_WS"
go default "$DEMO_RAW" "$DEMO_WM" $demo
go jpeg_layer "$DEMO_RAW" "$DEMO_JL" $demo
go fern_t38_free "$FERN_RAW" "$FERN_WM" "$FERN_WS" 12
go fern_t38j_free "$FERN_RAW" "$FERN_JL" "$FERN_WS" 12
go default_free "$DEMO_RAW" "$DEMO_WM" $demo 12
go jpeg_layer_free "$DEMO_RAW" "$DEMO_JL" $demo 12
# The simulator: each file read as each renderer shows it, through JPEG 90, as the owner.
sim=$O/simulated.tsv
printf 'file\tconventions\theld-out views\tsingle-view BER (owner, JPEG 90)\n' > "$sim"
for f in "demo default:$DEMO_RAW:$DEMO_WM:$demo" "demo jpeg layer:$DEMO_RAW:$DEMO_JL:$demo" \
         "fern default:$FERN_RAW:$FERN_WM:$FERN_WS" "fern jpeg layer:$FERN_RAW:$FERN_JL:$FERN_WS"; do
  IFS=: read -r label raw wm scene <<< "$f"
  for c in watergs web playcanvas; do
    line=$("$B" extract --input_path "$wm" --raw_path "$raw" --workspace_path "$scene" --downscale 2 \
      --message text:WGS-26 --split test --render_conventions $c --image_attack jpeg:90 2>&1 |
      grep "owner's reading): single views")
    printf '%s\t%s\t%s\n' "$label" "$c" "${line#*: }" >> "$sim"
  done
done
cat "$sim"
