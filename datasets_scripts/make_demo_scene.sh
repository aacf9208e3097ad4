#!/usr/bin/env bash
# Regenerates the embedded demo scene: renders demo_scene.pov with POV-Ray from two rings of 24 cameras
# (48 views, 480x360) and reconstructs it with COLMAP (CPU SIFT, exhaustive matching, incremental mapper).
#
# Usage: bash datasets_scripts/make_demo_scene.sh [--variant 1|2] [--debug] [out_dir]
#   out_dir defaults to datasets_scripts/demo_scene (variant 1, the committed scene) and
#   datasets_scripts/demo_scene_v2 (variant 2). Writes:
#     out_dir/images/view_NNN.jpg          JPEG quality 88, no render-date metadata
#     out_dir/sparse/0/{cameras,images,points3D}.bin
#     out_dir/ground_truth/{cameras,images,points3D}.txt   the POV-Ray poses as a COLMAP text model
#                                                          (world = POV-Ray (x, z, y), z up; match by NAME)
# --debug keeps COLMAP's database and logs (OUT_DIR/logs), or the scratch folder of a failed run.
# Needs: povray, povray-includes, colmap (3.8), python3. Meant to be deterministic: single-threaded
# rendering, matching and mapping, COLMAP's fixed default seed (see README for what was checked).
set -euo pipefail

script_dir="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
variant=1
debug=0
out_dir=""
while [ $# -gt 0 ]; do
  case "$1" in
    --variant) variant="${2:?--variant needs 1 or 2}"; shift 2 ;;
    --debug) debug=1; shift ;;
    -h|--help) sed -n '2,14p' "$0"; exit 0 ;;
    -*) echo "make_demo_scene: unknown option $1" >&2; exit 2 ;;
    *) out_dir="$1"; shift ;;
  esac
done
case "$variant" in
  1) default_dir="$script_dir/demo_scene" ;;
  2) default_dir="$script_dir/demo_scene_v2" ;;
  *) echo "make_demo_scene: --variant must be 1 or 2, got '$variant'" >&2; exit 2 ;;
esac
out_dir="${out_dir:-$default_dir}"

for tool in povray colmap python3; do
  command -v "$tool" >/dev/null || { echo "make_demo_scene: '$tool' not found (run scripts/install_deps.sh --all)" >&2; exit 1; }
done

readonly width=480 height=360 fov_deg=60 jpeg_quality=88
tools="$script_dir/demo_scene_tools.py"
start_seconds=$SECONDS
export QT_QPA_PLATFORM=offscreen

# Build everything in a scratch folder next to the output and move it into place at the end, so a failed
# run never leaves a half-written scene.
mkdir -p "$(dirname "$out_dir")"
work="$(mktemp -d "${out_dir%/}.tmp.XXXXXX")"
# --debug keeps the scratch folder of a failed run, and the database and logs of a good one (OUT_DIR/logs).
cleanup() { if [ "$debug" -eq 1 ]; then echo "make_demo_scene: scratch folder kept: $work" >&2; else rm -rf "$work"; fi; }
trap cleanup EXIT
mkdir -p "$work/images" "$work/sparse" "$work/logs"

echo "make_demo_scene: variant $variant -> $out_dir"
python3 "$tools" poses "$variant" "$width" "$height" "$fov_deg" "$work/ground_truth" >"$work/views.txt"
num_views=$(wc -l <"$work/views.txt")

echo "make_demo_scene: rendering $num_views views at ${width}x${height} with POV-Ray"
while read -r name cam_x cam_y cam_z look_x look_y look_z; do
  # One render thread: POV-Ray's multithreaded antialiasing gives slightly different pixels from run to
  # run. POV-Ray writes the render date into JPEG comments; strip it so output is reproducible.
  povray -I"$script_dir/demo_scene.pov" +O"$work/images/$name" +FJ Compression=$jpeg_quality \
    +W$width +H$height -D -V +A0.3 +R3 +WT1 \
    Declare=Variant="$variant" Declare=FovDeg=$fov_deg \
    Declare=CamX="$cam_x" Declare=CamY="$cam_y" Declare=CamZ="$cam_z" \
    Declare=LookX="$look_x" Declare=LookY="$look_y" Declare=LookZ="$look_z" \
    >"$work/logs/povray_$name.log" 2>&1 \
    || { echo "make_demo_scene: POV-Ray failed on $name:" >&2; tail -20 "$work/logs/povray_$name.log" >&2; exit 1; }
  python3 "$tools" strip-jpeg "$work/images/$name"
done <"$work/views.txt"
echo "make_demo_scene: rendered in $((SECONDS - start_seconds)) s"

# PINHOLE with the exact intrinsics, held fixed: the renders are exact pinholes (POV-Ray samples pixel
# centres, so the principal point is the image centre in COLMAP's convention), pinhole scenes need no
# undistortion before 3DGS training (like the output of Inria's convert.py), and letting bundle adjustment
# refine the focal length on this ring-shaped capture drove fx and fy far apart (180 and 75 px for a true 416).
focal=$(awk -v w=$width -v fov=$fov_deg 'BEGIN { printf "%.6f", (w / 2) / (sin(fov * 3.14159265358979 / 360) / cos(fov * 3.14159265358979 / 360)) }')
camera_params="$focal,$focal,$((width / 2)),$((height / 2))"
database="$work/database.db"

run_colmap() {
  local step="$1"; shift
  colmap "$step" "$@" >"$work/logs/colmap_$step.log" 2>&1 \
    || { echo "make_demo_scene: colmap $step failed:" >&2; tail -30 "$work/logs/colmap_$step.log" >&2; exit 1; }
}

echo "make_demo_scene: colmap feature_extractor (CPU SIFT, PINHOLE $camera_params)"
# One thread: with several, COLMAP numbers the images in the order their features finish, and that order
# changes matching and mapping (keypoints themselves were identical).
run_colmap feature_extractor --database_path "$database" --image_path "$work/images" \
  --ImageReader.camera_model PINHOLE --ImageReader.single_camera 1 \
  --ImageReader.camera_params "$camera_params" \
  --SiftExtraction.use_gpu 0 --SiftExtraction.num_threads 1 \
  --SiftExtraction.max_num_features 4096
echo "make_demo_scene: colmap exhaustive_matcher"
# One thread: RANSAC draws from per-thread generators, so a single thread makes the matches reproducible.
run_colmap exhaustive_matcher --database_path "$database" \
  --SiftMatching.use_gpu 0 --SiftMatching.num_threads 1
echo "make_demo_scene: colmap mapper"
run_colmap mapper --database_path "$database" --image_path "$work/images" --output_path "$work/sparse" \
  --Mapper.num_threads 1 --Mapper.ba_refine_focal_length 0 --Mapper.ba_refine_principal_point 0 \
  --Mapper.ba_refine_extra_params 0

if [ ! -f "$work/sparse/0/images.bin" ]; then
  echo "make_demo_scene: COLMAP produced no model" >&2; exit 1
fi
if [ -d "$work/sparse/1" ]; then
  echo "make_demo_scene: COLMAP split the scene into several models ($(find "$work/sparse" -mindepth 1 -maxdepth 1 -printf '%f '))" >&2
  exit 1
fi
rm -f "$work/sparse/0/project.ini"

run_colmap model_analyzer --path "$work/sparse/0"
analysis="$work/logs/colmap_model_analyzer.log"
registered=$(sed -n 's/.*Registered images: *\([0-9]*\).*/\1/p' "$analysis")
points=$(sed -n 's/.*Points: *\([0-9]*\).*/\1/p' "$analysis")
reprojection=$(sed -n 's/.*Mean reprojection error: *\([0-9.]*\).*/\1/p' "$analysis")
track_length=$(sed -n 's/.*Mean track length: *\([0-9.]*\).*/\1/p' "$analysis")
echo "make_demo_scene: registered images $registered / $num_views, points $points," \
  "mean track length $track_length, mean reprojection error ${reprojection}px"
if [ "$registered" != "$num_views" ]; then
  echo "make_demo_scene: only $registered of $num_views images registered" >&2
  exit 1
fi
python3 "$tools" compare "$work/sparse/0" "$work/ground_truth"

if [ "$debug" -eq 1 ]; then mv "$database" "$work/logs/"; else rm -f "$database"; fi
rm -f "$work/views.txt"
[ "$debug" -eq 1 ] || rm -rf "$work/logs"
rm -rf "$out_dir"
mv "$work" "$out_dir"
trap - EXIT
chmod -R a+rX "$out_dir"
echo "make_demo_scene: wrote $out_dir ($(du -sh "$out_dir" | cut -f1)) in $((SECONDS - start_seconds)) s"
