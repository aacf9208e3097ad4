#!/usr/bin/env bash
# Installs every Debian package watergs needs to build, test and regenerate its data.
# Idempotent: packages already present are skipped without touching the network.
set -euo pipefail
pkgs=(build-essential cmake git pkg-config clang-format
  libeigen3-dev libopencv-dev libceres-dev libboost-program-options-dev
  libgoogle-glog-dev libgtest-dev libgmock-dev nlohmann-json3-dev libnanoflann-dev libomp-dev zlib1g-dev libzstd-dev
  colmap)
# Regeneration only: datasets_scripts/make_demo_scene.sh (POV-Ray renders) and the download_*.sh scripts.
# The committed demo scene needs none of them; they are small, so they are installed anyway.
pkgs+=(povray povray-includes unzip curl)
# Fuzzing only (scripts/fuzz.sh): clang and its libFuzzer/sanitizer runtimes.
pkgs+=(clang libclang-rt-14-dev)
# Accuracy-vs-time plots (datasets_scripts/sweep_*_time.sh, pareto_plot.py, tested by CTest): PNGs via gnuplot.
pkgs+=(gnuplot-nox python3)
# Batch runs (scripts/slurm/): the CTest test starts a real single-node Slurm (slurmctld, slurmd, munged);
# python3-yaml checks the Kubernetes manifests (scripts/k8s/).
pkgs+=(slurm-wlm munge python3-yaml)
# The ownership report's browser test (tests/plugin/report_cli_test.cc, scripts/screenshot_report.sh): headless Chromium.
pkgs+=(chromium)
# The Python module (python/, docs/python.md): pybind11 and the headers to build it, numpy for its arrays, pytest for its tests.
pkgs+=(pybind11-dev python3-dev python3-numpy python3-pytest)
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install_deps: all ${#pkgs[@]} packages present"
  exit 0
fi
echo "install_deps: installing ${missing[*]}"
SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO=sudo
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
