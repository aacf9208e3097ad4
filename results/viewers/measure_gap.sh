#!/usr/bin/env bash
# The renderer gap (issue 54 item 1): PSNR of each real web viewer's screenshot (tests/viewer)
# against watergs' render of the same model at the same camera, on the demo's 6 held-out cameras
# (every 8th view, 240x180), with the viewers' defaults and with each convention switched that
# the viewer lets one switch, to say where the gap comes from.
#   results/viewers/measure_gap.sh MODEL OUT
# Writes OUT/watergs[_shN]/ (watergs' renders and cameras.json), OUT/<viewer>_<config>/ (the
# screenshots and viewer.json), OUT/<viewer>_<config>.json and .txt (compare.py) and appends one
# line per configuration to OUT/gap.tsv: viewer, configuration, reference, mean PSNR, per camera.
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
model=${1:?usage: measure_gap.sh MODEL OUT}; out=${2:?OUT}
bin="${WATERGS_BIN:-$root/build/plugin/watergs}"
scene="${SCENE:-$root/datasets_scripts/demo_scene}"
python=/usr/bin/python3
mkdir -p "$out"
ref() {  # NAME [render options...]: watergs' renders of the held-out views
  local name=$1; shift
  [ -f "$out/$name/cameras.json" ] || "$bin" render --input_path "$model" --workspace_path "$scene" \
    --downscale 2 --split test --output_path "$out/$name" "$@" > "$out/$name.log" 2>&1
}
ref watergs
ref watergs_sh0 --sh_degree 0
ref watergs_sh2 --sh_degree 2
tsv() {  # COMPARE_JSON VIEWER CONFIG REFERENCE: one line of OUT/gap.tsv
  "$python" - "$@" >> "$out/gap.tsv" <<'PY'
import json, sys
j = json.load(open(sys.argv[1]))
print("\t".join(sys.argv[2:5] + ["%.2f" % j["mean_psnr"]] + ["%.2f" % r["psnr"] for r in j["images"]]))
PY
}
shoot() {  # VIEWER CONFIG REFERENCE [--set K=V ...]
  local viewer=$1 config=$2 reference=$3; shift 3
  local dir="$out/${viewer}_$config"
  if [ ! -f "$dir/viewer.json" ]; then
    local start=$SECONDS
    node "$root/tests/viewer/render.mjs" --viewer "$viewer" --model "$model" \
      --cameras "$out/watergs/cameras.json" --output "$dir" "$@" > "$dir.render.log" 2>&1
    echo "wall $((SECONDS - start)) s" >> "$dir.render.log"
  fi
  "$python" "$root/tests/viewer/compare.py" "$out/$reference" "$dir" --shift 2 --overlay "$dir/overlay_vs_$reference" \
    --json "$dir.vs_$reference.json" > "$dir.vs_$reference.txt"
  tsv "$dir.vs_$reference.json" "$viewer" "$config" "$reference"
  tail -n 1 "$dir.vs_$reference.txt" | sed "s|^|$viewer $config vs $reference: |"
}
: > "$out/gap.tsv"
# gaussian-splats-3d: its defaults (SH degree 0), then SH degree 2 (its most), against watergs at
# the same degree and at the model's 3; then 2 + blending in half float (8-bit blending removed),
# 2 + antialiased (the Mip-Splatting compensation), 2 + no dilation (kernel2DSize 0).
shoot gs3d default watergs
shoot gs3d default watergs_sh0
shoot gs3d sh2 watergs_sh2 --set sphericalHarmonicsDegree=2
shoot gs3d sh2 watergs
shoot gs3d sh2_float watergs_sh2 --set sphericalHarmonicsDegree=2 --set floatTarget=true
shoot gs3d sh2_antialiased watergs_sh2 --set sphericalHarmonicsDegree=2 --set antialiased=true
shoot gs3d sh2_kernel0 watergs_sh2 --set sphericalHarmonicsDegree=2 --set kernel2DSize=0
# PlayCanvas: its defaults (unified rendering, compact work buffer, splats under 2 px dropped, SH
# as in the file), then each switched: the per-splat (non-unified) path, minPixelSize 0, the large
# (half-float colour) work buffer, antiAlias.
shoot playcanvas default watergs
shoot playcanvas minpixel0 watergs --set minPixelSize=0
shoot playcanvas large watergs --set dataFormat='"large"'
shoot playcanvas nonunified watergs --set unified=false
shoot playcanvas nonunified_minpixel0 watergs --set unified=false --set minPixelSize=0
shoot playcanvas antialias watergs --set antiAlias=true
# The gap explained: watergs renders the model with a viewer's conventions applied to the splats
# (emulate_viewer.py) and is compared with that viewer's default screenshots.
emulate() {  # VIEWER NAME OPS [CULL]: OUT/emulated_NAME/ = watergs' renders of the emulated model
  local viewer=$1 name=$2 ops=$3 cull=${4:-} dir="$out/emulated_$2"
  if [ ! -f "$dir/done" ]; then
    rm -rf "$dir" "$dir.plys"
    mkdir -p "$dir"
    if [ -n "$cull" ]; then
      "$python" "$root/results/viewers/emulate_viewer.py" "$model" "$dir.plys" "$ops" \
        --cameras "$out/watergs/cameras.json" --cull "$cull" > "$dir.log"
    else
      "$python" "$root/results/viewers/emulate_viewer.py" "$model" "$dir.plys" "$ops" > "$dir.log"
    fi
    for ply in "$dir.plys"/*.ply; do
      "$bin" render --input_path "$ply" --workspace_path "$scene" --downscale 2 --split test --align off \
        --output_path "$dir.tmp" >> "$dir.log" 2>&1
      local stem; stem=$(basename "$ply" .ply)
      if [ "$stem" = model ]; then cp "$dir.tmp"/*.png "$dir/"; else cp "$dir.tmp/$stem.png" "$dir/"; fi
    done
    rm -rf "$dir.tmp" "$dir.plys"
    touch "$dir/done"
  fi
  local shots="$out/${viewer}_default"
  "$python" "$root/tests/viewer/compare.py" "$dir" "$shots" --json "$shots.vs_emulated_$name.json" \
    > "$shots.vs_emulated_$name.txt"
  tsv "$shots.vs_emulated_$name.json" "$viewer" default "emulated_$name"
  tail -n 1 "$shots.vs_emulated_$name.txt" | sed "s|^|$viewer default vs watergs emulating $name: |"
}
emulate gs3d sh0_clamp01 sh0,clamp01
emulate gs3d sh0_cull1.2 sh0 1.2
emulate gs3d sh0_clamp01_cull1.2 sh0,clamp01 1.2
