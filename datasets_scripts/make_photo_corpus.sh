#!/usr/bin/env bash
# Assembles an offline corpus of natural photographs for `watergs train_decoder` from Debian
# packages (desktop wallpapers and OpenCV's sample photos), converts each to a JPEG whose short
# side is SHORT_SIDE pixels, and splits it deterministically into train/ and heldout/.
#
# Usage: datasets_scripts/make_photo_corpus.sh OUTPUT_DIR [SHORT_SIDE=384]
# Idempotent: packages already installed are not touched, converted files are not redone.
# Split: an image is held out when the first hex digit of the MD5 of its corpus name is 0 or 1
# (about 1 in 8), so adding or removing a package never moves the other images.
set -euo pipefail
out=${1:?usage: make_photo_corpus.sh OUTPUT_DIR [SHORT_SIDE]}
short=${2:-384}
pkgs=(plasma-workspace-wallpapers gnome-backgrounds mate-backgrounds ukui-wallpapers opencv-doc
  imagemagick)
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "make_photo_corpus: installing ${missing[*]}"
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO=sudo
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
convert_bin=/usr/bin/convert
[ -x "$convert_bin" ] || { echo "make_photo_corpus: $convert_bin missing" >&2; exit 1; }

sources=()
# Plasma wallpapers: one picture per folder, its largest size.
for d in /usr/share/wallpapers/*/contents/images; do
  [ -d "$d" ] || continue
  best=$(ls "$d" | grep -i -E '\.(jpg|jpeg|png)$' | sort -t x -k1,1n | tail -1)
  [ -n "$best" ] && sources+=("$d/$best")
done
# GNOME, MATE and UKUI backgrounds (photographs and a few renders; vector art is skipped).
while IFS= read -r f; do sources+=("$f"); done < <(find /usr/share/backgrounds -type f \
  \( -iname '*.jpg' -o -iname '*.jpeg' -o -iname '*.png' -o -iname '*.webp' \) | sort)
# OpenCV sample photographs (not its charts, logos, calibration boards or text images).
cv=/usr/share/doc/opencv-doc/examples/data
for n in aero1 aero3 apple baboon building butterfly fruits home leuvenA leuvenB lena messi5 \
  orange starry_night HappyFish aloeL aloeR box_in_scene graf1 graf3 ela_original \
  licenseplate_motion tsukuba_l Blender_Suzanne1 basketball1 pic1 pic3 pic5 sudoku stuff; do
  for e in jpg png; do [ -f "$cv/$n.$e" ] && sources+=("$cv/$n.$e"); done
done

mkdir -p "$out/train" "$out/heldout"
count_train=0; count_held=0
for src in "${sources[@]}"; do
  # Corpus name: package folder + file name, so equal file names never collide.
  name=$(echo "$src" | sed -e 's|/contents/images/.*||' -e 's|^/usr/share/||' -e 's|^doc/||' \
    -e 's|[^A-Za-z0-9]|_|g')
  digit=$(printf '%s' "$name" | md5sum | cut -c1)
  split=train; [[ "$digit" == 0 || "$digit" == 1 ]] && split=heldout
  dst="$out/$split/$name.jpg"
  if [ ! -s "$dst" ]; then
    # Skip images smaller than the working resolution (icons, tiles).
    size=$($convert_bin "$src" -format '%w %h' info: 2>/dev/null | head -1) || continue
    w=${size% *}; h=${size#* }
    [ -n "$w" ] && [ "$w" -ge "$short" ] && [ "$h" -ge "$short" ] || continue
    $convert_bin "$src[0]" -auto-orient -colorspace sRGB -alpha remove -resize "${short}x${short}^" \
      -quality 95 "$dst.tmp.jpg" && mv "$dst.tmp.jpg" "$dst"
  fi
  [ "$split" == train ] && count_train=$((count_train + 1)) || count_held=$((count_held + 1))
done
echo "make_photo_corpus: $count_train train, $count_held held-out photos in $out (short side $short)"
