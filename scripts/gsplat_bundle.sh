#!/usr/bin/env bash
# Packs gsplat's source (nerfstudio-project/gsplat, a checkout or a bare clone made here, e.g. by
# the fetch tool) with what its JIT build needs and a bare CUDA machine lacks (glm's headers, the
# pure-Python rich and packaging it imports; from Debian packages downloaded here, not installed), for the
# `gsplat` stage of scripts/gpu_check.sh: gsplat and watergs timing the same rasterization on the
# same card (docs/cuda.md). Ninja (PyTorch's JIT builds need it) comes along. PyTorch is not packed: the stage uses the device's, or says there is none.
#   bash scripts/gsplat_bundle.sh --source GSPLAT_GIT_DIR [--commit REV] [--out DIR]   (project root)
# Checked against gsplat 1.6 (90d7b4b3, 2026): a JIT build on first import (gsplat/cuda/build.py)
# with glm in csrc/third_party/glm; another revision may lay its build out differently.
# Writes OUT/gsplat.tar.xz (OUT defaults to .gpu), with OUT/gsplat.commit naming the revision.
set -euo pipefail
die() { echo "gsplat_bundle: $*" >&2; exit 2; }
source_dir="" commit=HEAD out=.gpu
while [ $# -gt 0 ]; do
  case "$1" in
    --source|--commit|--out)
      [ $# -ge 2 ] || die "$1 needs a value"
      case "$1" in --source) source_dir="$2" ;; --commit) commit="$2" ;; --out) out="$2" ;; esac
      shift 2 ;;
    -h|--help) awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; exit 0 ;;
    *) die "unknown argument '$1'" ;;
  esac
done
[ -n "$source_dir" ] || die "--source: a gsplat git checkout or bare clone is needed"
rev=$(git -C "$source_dir" rev-parse --verify -q "$commit^{commit}" 2> /dev/null) || die "$source_dir: no revision '$commit'"
stage=$(mktemp -d)
trap 'rm -rf "$stage"' EXIT
mkdir -p "$stage/gsplat" "$stage/deps" "$stage/debs"
# The Python package alone (the snapshot may lack large doc assets).
git -C "$source_dir" archive "$rev" gsplat | tar -xf - -C "$stage/gsplat"
(cd "$stage/debs" && apt-get download libglm-dev python3-rich python3-markdown-it python3-mdurl python3-packaging ninja-build \
  > /dev/null 2>&1) || die "apt-get download failed (glm headers and rich come from Debian packages)"
for deb in "$stage"/debs/*.deb; do dpkg-deb -x "$deb" "$stage/deps"; done
# gsplat's build looks for glm in its submodule's place (csrc/third_party/glm/glm/...).
glm_dir="$stage/gsplat/gsplat/cuda/csrc/third_party/glm"
mkdir -p "$glm_dir" && cp -r "$stage/deps/usr/include/glm" "$glm_dir/"
mkdir -p "$out"
echo "$rev" > "$out/gsplat.commit"
tar -C "$stage" -cf - gsplat deps/usr/lib/python3 deps/usr/bin/ninja | xz -T2 -6 > "$out/gsplat.tar.xz"
echo "gsplat_bundle: gsplat $rev, $(du -h "$out/gsplat.tar.xz" | cut -f1) in $out/gsplat.tar.xz"
