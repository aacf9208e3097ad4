# shellcheck shell=bash
# Shared helpers for the download_*.sh scripts (sourced, not run).
# Downloads resume where they stopped, are checked against a known MD5 where one is published, and
# land in a cache folder (WATERGS_DOWNLOAD_CACHE, default <out_dir>/.downloads) that survives re-runs.

log() { echo "$(basename "$0"): $*" >&2; }
die() { log "error: $*"; exit 1; }

# from_option ARGS...: a leading `--from DIR` (a local copy instead of the download): sets from_dir
# (empty without it) and from_shift (how many arguments it took: shift "$from_shift" after the call).
from_option() {
  from_dir="" from_shift=0
  if [ "${1:-}" == "--from" ]; then
    [ $# -ge 2 ] || die "--from needs a folder"
    [ -d "$2" ] || die "$2: no such folder (--from)"
    from_dir="$2" from_shift=2
  fi
}

# sparse_clone URL DIR PATTERN...: a blob-filtered, depth-1 clone of URL into DIR with only the paths
# matching the patterns checked out (git sparse-checkout, no-cone); an existing DIR/.git is reused.
sparse_clone() {
  local url="$1" dir="$2"
  shift 2
  require_tools git
  [ -d "$dir/.git" ] && return 0
  log "cloning $url (sparse: $*)"
  rm -rf "$dir"
  git clone --filter=blob:none --no-checkout --depth 1 "$url" "$dir" || die "git clone failed"
  git -C "$dir" sparse-checkout set --no-cone "$@"
  git -C "$dir" checkout || die "git checkout of the sparse clone failed"
}

require_tools() {
  local tool
  for tool in "$@"; do
    command -v "$tool" >/dev/null || die "'$tool' is required (Debian: apt-get install $tool)"
  done
}

# fetch URL DEST [MD5]: downloads URL to DEST (resuming a partial DEST.part), then checks MD5 if given.
fetch() {
  local url="$1" dest="$2" md5="${3:-}"
  if [ -f "$dest" ]; then
    log "using cached $dest"
  else
    log "downloading $url"
    mkdir -p "$(dirname "$dest")"
    if command -v curl >/dev/null; then
      curl -fL --retry 5 --retry-delay 5 -C - -o "$dest.part" "$url" || die "download failed: $url"
    elif command -v wget >/dev/null; then
      wget -c -t 5 -O "$dest.part" "$url" || die "download failed: $url"
    else
      die "neither curl nor wget is installed (apt-get install curl)"
    fi
    mv "$dest.part" "$dest"
  fi
  verify_md5 "$dest" "$md5"
}

# verify_md5 FILE [MD5]: checks FILE, or prints its MD5 so it can be recorded when none is known.
verify_md5() {
  local file="$1" expected="${2:-}" actual
  actual="$(md5sum "$file" | cut -d' ' -f1)"
  if [ -z "$expected" ]; then
    log "no published checksum for $(basename "$file"); its MD5 is $actual"
  elif [ "$actual" != "$expected" ]; then
    rm -f "$file"
    die "$(basename "$file") has MD5 $actual, expected $expected (removed; run again to re-download)"
  else
    log "checksum OK: $(basename "$file")"
  fi
}

# fetch_gdrive FILE_ID DEST [MD5]: Google Drive file; uses gdown when installed, else the
# confirm=t download endpoint that skips the virus-scan page for large files.
fetch_gdrive() {
  local id="$1" dest="$2" md5="${3:-}"
  if [ ! -f "$dest" ] && command -v gdown >/dev/null; then
    log "downloading Google Drive file $id with gdown"
    gdown --continue "$id" -O "$dest.part" || die "gdown failed for $id"
    mv "$dest.part" "$dest"
  fi
  fetch "https://drive.usercontent.google.com/download?id=${id}&export=download&confirm=t" "$dest" "$md5"
  if head -c 512 "$dest" | grep -qi "<html"; then
    rm -f "$dest"
    die "Google Drive returned a web page instead of $(basename "$dest") (quota or link change);" \
      "download it by hand into $(dirname "$dest") and run again"
  fi
}

# unpack_folder ZIP PREFIX DEST: extracts the entries under PREFIX/ of ZIP into DEST (replacing DEST),
# through a scratch folder so an interrupted run leaves no half-filled DEST.
unpack_folder() {
  local zip="$1" prefix="$2" dest="$3" scratch
  scratch="$(mktemp -d "${dest%/}.unpacking.XXXXXX")"
  log "unpacking $prefix from $(basename "$zip")"
  unzip -q -o "$zip" "$prefix/*" -d "$scratch" || { rm -rf "$scratch"; die "cannot unpack $prefix from $zip"; }
  [ -d "$scratch/$prefix" ] || { rm -rf "$scratch"; die "$zip has no folder $prefix"; }
  rm -rf "$dest"
  mv "$scratch/$prefix" "$dest"
  rm -rf "$scratch"
}

# copy_folder SOURCE DEST: copies SOURCE to DEST (replacing DEST) through a scratch folder, as
# unpack_folder does.
copy_folder() {
  local source="$1" dest="$2" scratch
  scratch="$(mktemp -d "${dest%/}.copying.XXXXXX")"
  log "copying $source"
  cp -r "$source/." "$scratch/" || { rm -rf "$scratch"; die "cannot copy $source to $scratch"; }
  rm -rf "$dest"
  mv "$scratch" "$dest"
}

# write_manifest SCENE: SCENE/photos.sha256, the SHA-256 of every photo (images*/) and model file
# (sparse/), paths relative to SCENE, sorted; `sha256sum -c photos.sha256` in SCENE checks a copy.
write_manifest() {
  local scene="$1"
  (cd "$scene" && find . -type f \( -path './images*' -o -path './sparse/*' -o -name poses_bounds.npy \) \
     -printf '%P\n' | LC_ALL=C sort \
     | xargs -d '\n' sha256sum > photos.sha256.part && mv photos.sha256.part photos.sha256) \
    || die "cannot write $scene/photos.sha256"
  log "manifest: $scene/photos.sha256 ($(wc -l < "$scene/photos.sha256") files)"
}

# count_images DIR: number of image files directly in DIR.
count_images() {
  find "$1" -maxdepth 1 -type f \( -iname '*.jpg' -o -iname '*.jpeg' -o -iname '*.png' \) | wc -l
}

# match_downscaled_names SCENE: the CLI reads SCENE/images_N/<name> with <name> exactly as in
# sparse/0 (the name of the full-resolution image). A downscaled folder whose files carry other names
# but pair one-to-one in sorted order is renamed to those names (decoders look at the content, not the
# extension); one that cannot be paired is removed, and the CLI then resizes the full images itself.
match_downscaled_names() {
  local scene="$1" folder full_names small_names i
  mapfile -t full_names < <(find "$scene/images" -mindepth 1 -maxdepth 1 -printf '%f\n' | LC_ALL=C sort)
  for folder in "$scene"/images_*; do
    [ -d "$folder" ] || continue
    mapfile -t small_names < <(find "$folder" -mindepth 1 -maxdepth 1 -printf '%f\n' | LC_ALL=C sort)
    if [ "${small_names[*]}" == "${full_names[*]}" ]; then
      continue
    fi
    if [ "${#small_names[@]}" -ne "${#full_names[@]}" ]; then
      log "warning: $folder holds ${#small_names[@]} files, images holds ${#full_names[@]}: removing it"
      rm -rf "$folder"
      continue
    fi
    log "renaming $folder to the full-resolution image names (sorted order)"
    for i in "${!small_names[@]}"; do
      mv "$folder/${small_names[$i]}" "$folder/.renaming_$i"
    done
    for i in "${!small_names[@]}"; do
      mv "$folder/.renaming_$i" "$folder/${full_names[$i]}"
    done
  done
}

# check_colmap_scene SCENE [--photos_only_ok]: the layout the watergs CLI expects, or a clear
# error; with --photos_only_ok (a local copy) a scene without sparse/0 is laid out with a warning.
check_colmap_scene() {
  local scene="$1" photos_only_ok="${2:-}" file
  [ -d "$scene/images" ] || die "$scene/images is missing"
  local reconstruct="watergs reconstruct --image_path $scene/images --workspace_path ${scene}_reconstructed"
  if [ ! -d "$scene/sparse/0" ] && [ "$photos_only_ok" == --photos_only_ok ]; then
    # A copy of the photos alone (and poses_bounds.npy): the poses come from reconstruct.
    log "warning: $scene has no COLMAP model (sparse/0): reconstruct the poses with: $reconstruct"
    log "ready: $scene ($(count_images "$scene/images") images, no model)"
    return
  fi
  for file in cameras images points3D; do
    if [ "$file" == images ] && [ ! -f "$scene/sparse/0/images.bin" ] && [ ! -f "$scene/sparse/0/images.txt" ]; then
      log "warning: $scene/sparse/0 has no images.bin (a copy that left it out): reconstruct the" \
        "poses with: $reconstruct"
      continue
    fi
    [ -f "$scene/sparse/0/$file.bin" ] || [ -f "$scene/sparse/0/$file.txt" ] \
      || die "$scene/sparse/0/$file.bin (or .txt) is missing"
  done
  local summary
  summary="$(count_images "$scene/images") images"
  local folder
  for folder in "$scene"/images_*; do
    [ -d "$folder" ] && summary+=", $(basename "$folder")"
  done
  log "ready: $scene ($summary)"
}
