#!/usr/bin/env bash
# Installs the Debian packages watergs needs, by group, and prints one line per group: what it is
# for and its packages (those missing, if any, are then installed).
#   bash scripts/install_deps.sh          build: what the demo (scripts/run_demo.sh) needs
#   bash scripts/install_deps.sh --tests  build + tests: what the whole test suite needs
#   bash scripts/install_deps.sh --all    build + tests + regen + fuzz: also the data regeneration and
#                                         fuzzing tools
# Idempotent: packages already present are skipped without touching the network.
set -euo pipefail
want_tests=0 want_all=0
for arg in "$@"; do
  case "$arg" in
    --tests) want_tests=1 ;;
    --all) want_tests=1 want_all=1 ;;
    -h|--help) sed -n '2,8p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "install_deps: unknown option $arg (--tests, --all)" >&2; exit 2 ;;
  esac
done

groups=() whys=() lists=() wanted=() options=()
group() {  # NAME WANTED OPTION WHY PACKAGES...
  groups+=("$1") wanted+=("$2") options+=("$3") whys+=("$4")
  shift 4
  lists+=("$*")
}
# The default build compiles the tests too (CMake needs GoogleTest to configure), so it is here.
group build 1 "" "compiler, CMake and the libraries watergs links, GoogleTest (the default build compiles the tests); all the demo needs" \
  build-essential cmake git pkg-config libeigen3-dev libopencv-dev libceres-dev \
  libboost-program-options-dev libgoogle-glog-dev libgtest-dev libgmock-dev nlohmann-json3-dev \
  libnanoflann-dev libomp-dev zlib1g-dev libssl-dev libzstd-dev
group tests "$want_tests" --tests "the test suite: clang-format (format check), COLMAP 3.8 (compatibility tests), gnuplot (plot check), a single-node Slurm with munge (batch test), PyYAML (Kubernetes manifests), Chromium (report screenshot test), pybind11, Python headers, numpy and pytest (the Python module and its tests)" \
  clang-format colmap gnuplot-nox python3 slurm-wlm munge python3-yaml chromium \
  pybind11-dev python3-dev python3-numpy python3-pytest
group regen "$want_all" --all "regenerating the data: POV-Ray (datasets_scripts/make_demo_scene.sh), unzip and curl (download_*.sh); the committed data needs none" \
  povray povray-includes unzip curl
group fuzz "$want_all" --all "fuzzing (scripts/fuzz.sh): clang and its libFuzzer and sanitizer runtimes" \
  clang libclang-rt-14-dev

missing=()
for i in "${!groups[@]}"; do
  if [ "${wanted[$i]}" -ne 1 ]; then
    echo "install_deps: ${groups[$i]}: not installed (${options[$i]} adds it): ${whys[$i]}"
    continue
  fi
  group_missing=()
  for p in ${lists[$i]}; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || group_missing+=("$p")
  done
  if [ ${#group_missing[@]} -eq 0 ]; then
    state="all present"
  else
    state="installing ${group_missing[*]}"
  fi
  echo "install_deps: ${groups[$i]}: ${whys[$i]}: ${lists[$i]} ($state)"
  missing+=(${group_missing[@]+"${group_missing[@]}"})
done
[ ${#missing[@]} -eq 0 ] && exit 0
SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO=sudo
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
