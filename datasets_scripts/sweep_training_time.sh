#!/usr/bin/env bash
# What 3DGS training accuracy costs in time: trains a COLMAP workspace once per grid setting
# with held-out PSNR logged at many iterations, so each run gives a PSNR-against-time curve;
# collects them into one CSV with the Pareto front (least time, highest PSNR) and plots it.
set -euo pipefail

usage() {
  cat <<'EOF'
Usage: datasets_scripts/sweep_training_time.sh [options]

Trains a workspace once per grid setting (watergs train --split train, every 8th view held out) and
writes, under OUT:
  training.csv   setting, downscale, max_iterations, densify_until_iter, iteration,
                 train_seconds (training steps only), test_psnr, test_ssim, num_gaussians,
                 run_wall_seconds (whole command), load_avg_after, pareto (1 = on the front of
                 the runs at that downscale: PSNR is against ground truth at that resolution),
                 final (1 = last test of a run), pareto_final (front among run ends only)
  training.png   PSNR against training time, one curve per setting, front marked (gnuplot)
  commands.txt   the exact commands run
  runs/<setting>/  each run's train_log.jsonl, report.json, train_stdout.txt
                 (the PLYs are deleted unless --keep_models)

Options:
  --workspace DIR     COLMAP workspace (default datasets_scripts/demo_scene)
  --binary PATH       watergs executable (default build/plugin/watergs)
  --out DIR           output folder (default results/accuracy_vs_time/training)
  --grid LIST         settings D:N[:U] comma-separated: downscale D, N iterations, density
                      control until iteration U (default Inria's 15000; 0 = none)
                      (default 4:1000,4:1500,4:2000,4:3000,4:3000:0,4:3000:1000,
                      2:1000,2:2000,2:3000)
  --test_every K      held-out test every K iterations (default 250)
  --threads T         --num_threads for train (default 1)
  --seed S            --seed for train (default 0)
  --keep_models       keep each run's point_cloud.ply
  -h, --help          this text

Runs under `nice -n 10`. Train's position learning-rate schedule spans the run's own
--iterations, so a point at iteration i of an N-iteration run is not an i-iteration run: the
grid therefore holds runs of several lengths, and each run's last point is what a user who
trains that long gets.
EOF
}

die() { echo "sweep_training_time: $*" >&2; exit 1; }

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
workspace="$root/datasets_scripts/demo_scene"
binary="$root/build/plugin/watergs"
out="$root/results/accuracy_vs_time/training"
grid="4:1000,4:1500,4:2000,4:3000,4:3000:0,4:3000:1000,2:1000,2:2000,2:3000"
test_every=250
threads=1
seed=0
keep_models=0
while [ $# -gt 0 ]; do
  case "$1" in
    --workspace) workspace="${2:?--workspace needs a value}"; shift 2 ;;
    --binary) binary="${2:?--binary needs a value}"; shift 2 ;;
    --out) out="${2:?--out needs a value}"; shift 2 ;;
    --grid) grid="${2:?--grid needs a value}"; shift 2 ;;
    --test_every) test_every="${2:?--test_every needs a value}"; shift 2 ;;
    --threads) threads="${2:?--threads needs a value}"; shift 2 ;;
    --seed) seed="${2:?--seed needs a value}"; shift 2 ;;
    --keep_models) keep_models=1; shift ;;
    -h|--help) usage; exit 0 ;;
    *) usage >&2; die "unknown option '$1'" ;;
  esac
done

source "$(dirname "${BASH_SOURCE[0]}")/lib_sweep.sh"
require_watergs_workspace "$binary" "$workspace"
[[ "$test_every" =~ ^[1-9][0-9]*$ ]] || die "--test_every '$test_every': not a positive integer"
[[ "$threads" =~ ^[0-9]+$ ]] || die "--threads '$threads': not a non-negative integer"
command -v python3 >/dev/null || die "python3 not found"
plot="$root/datasets_scripts/pareto_plot.py"

IFS=',' read -r -a settings <<<"$grid"
for s in "${settings[@]}"; do
  [[ "$s" =~ ^(1|2|4|8):[1-9][0-9]*(:[0-9]+)?$ ]] || die "--grid item '$s': expected D:N or D:N:U (D in 1,2,4,8)"
done

mkdir -p "$out/runs"
commands="$out/.commands.txt.tmp"
{
  echo "# $(date -u +%FT%TZ) on $(hostname), $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg)"
  echo "# datasets_scripts/sweep_training_time.sh --workspace ${workspace#"$root"/} --grid $grid --test_every $test_every --threads $threads --seed $seed"
} >"$commands"

run_dirs=()
for s in "${settings[@]}"; do
  IFS=':' read -r ds iters until <<<"$s"
  until="${until:-15000}"
  name="ds${ds}_it${iters}"
  [ "$until" = 15000 ] || name="${name}_densify${until}"
  run="$out/runs/$name"
  rm -rf "$run.partial"
  mkdir -p "$run.partial"
  tests=$(seq -s, "$test_every" "$test_every" "$iters")
  case ",$tests," in *",$iters,"*) ;; *) tests="$tests,$iters" ;; esac
  cmd=(nice -n 10 "$binary" train --device cpu --workspace_path "$workspace" --output_path "$run.partial"
    --downscale "$ds" --iterations "$iters" --split train --test_iterations "$tests"
    --num_threads "$threads" --seed "$seed" --densify_until_iter "$until" --log_every 50)
  echo "${cmd[*]}" | sed -e "s#$run.partial#$run#" -e "s#$root/##g" >>"$commands"
  echo "sweep_training_time: $name ($(date -u +%T))" >&2
  t0=$(date +%s.%N)
  "${cmd[@]}" >"$run.partial/train_stdout.txt" 2>"$run.partial/train_stderr.txt" ||
    die "train failed for $name (see $run.partial/train_stderr.txt)"
  t1=$(date +%s.%N)
  wall=$(python3 -c "print(round($t1 - $t0, 3))")
  label="1/$ds res, $iters it"
  if [ "$until" = 0 ]; then label="$label, no densification"
  elif [ "$until" != 15000 ]; then label="$label, densify until $until"; fi
  python3 - "$run.partial/sweep_meta.json" "$label" "$ds" "$iters" "$until" "$wall" <<'PY'
import json, os, sys
path, label, ds, iters, until, wall = sys.argv[1:]
meta = {"setting": label, "downscale": int(ds), "iterations": int(iters),
        "densify_until_iter": int(until), "wall_seconds": float(wall),
        "load_avg_after": float(open("/proc/loadavg").read().split()[0])}
with open(path + ".tmp", "w") as f:
    json.dump(meta, f, indent=2)
os.replace(path + ".tmp", path)
PY
  # Progress bars and camera lists are not results; the PLY is large.
  rm -f "$run.partial/train_stderr.txt" "$run.partial/cameras.json" "$run.partial/checkpoint.ckpt"
  [ "$keep_models" = 1 ] || rm -f "$run.partial/point_cloud.ply"
  rm -rf "$run"
  mv "$run.partial" "$run"
  run_dirs+=("$run")
done

python3 "$plot" train-csv "${run_dirs[@]}" --out "$out/training.csv"
python3 "$plot" plot-train "$out/training.csv" --png "$out/training.png" \
  --title "3DGS training on $(basename "$workspace"): held-out PSNR against wall time"
echo "# finished $(date -u +%FT%TZ)" >>"$commands"
mv "$commands" "$out/commands.txt"
echo "sweep_training_time: wrote $out/training.csv, $out/training.png" >&2
