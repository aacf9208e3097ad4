#!/usr/bin/env bash
# Screenshots an HTML page (a `watergs report`) in headless Chromium, whole
# page, and records what a check of it needs:
#   scripts/screenshot_report.sh PAGE.html OUT.png [WIDTH]
# writes OUT.png (WIDTH, default 1100, by the page's height, 1 CSS px = 1
# pixel), OUT.json ({"width", "height", "images": [{id, x, y, width,
# height, natural_width, natural_height, complete}], "overflow": [...]}:
# each <img>'s content box (without its border) in the screenshot, measured
# after the page loaded; each table, pre or section wider than its
# container, as "table#attacks 1240 px in 1052 px") and OUT.console.txt (the
# console messages of both loads; a report has no script, so it should be
# empty). The boxes come from a copy of the page with a small probe script
# added at its end; the screenshot is of the page itself, at the same width.
# Exit 2 if Chromium is missing (CHROMIUM overrides /usr/bin/chromium).
set -euo pipefail
page="$1"
out="$2"
width="${3:-1100}"
chromium="${CHROMIUM:-/usr/bin/chromium}"
if [ ! -x "$chromium" ]; then
  echo "screenshot_report: no Chromium at $chromium (apt-get install chromium)" >&2
  exit 2
fi
[ -f "$page" ] || { echo "screenshot_report: $page: no such file" >&2; exit 1; }
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

# --no-sandbox: Chromium refuses to run as root with its sandbox (CI
# containers); the page is a local file. Scrollbars hidden so that the width
# is the layout width in both loads.
# file:// URL of a path, percent-encoded (spaces, '#', '?' in folder names).
file_url() {
  python3 -c 'import pathlib, sys; print(pathlib.Path(sys.argv[1]).resolve().as_uri())' "$1"
}
run_chromium() {
  timeout 60 "$chromium" --headless=new --no-sandbox --disable-gpu \
    --disable-dev-shm-usage --no-first-run --hide-scrollbars \
    --force-device-scale-factor=1 --user-data-dir="$work/profile" \
    --enable-logging=stderr --v=0 "$@"
}

cp "$page" "$work/probe.html"
cat >>"$work/probe.html" <<'EOF'
<script>
window.addEventListener('load', () => {
  const images = [];
  for (const img of document.images) {
    // The content box: the picture without the element's border.
    const box = img.getBoundingClientRect();
    images.push({id: img.id, x: box.left + img.clientLeft + scrollX,
                 y: box.top + img.clientTop + scrollY,
                 width: img.clientWidth, height: img.clientHeight,
                 natural_width: img.naturalWidth,
                 natural_height: img.naturalHeight, complete: img.complete});
  }
  // Tables and pre blocks wider than the box they stand in: cut off at the
  // right edge, or only seen by scrolling sideways. (Figures are left out:
  // their images scale to the grid cell, so at most the 1-px border passes
  // it, into the 14-px gap.)
  const overflow = [];
  for (const el of document.querySelectorAll('table, pre, section')) {
    const parent = el.parentElement;
    if (el.getBoundingClientRect().width > parent.clientWidth + 1 ||
        el.scrollWidth > el.clientWidth + 1) {
      overflow.push((el.id ? el.tagName.toLowerCase() + '#' + el.id
                           : el.tagName.toLowerCase()) + ' ' +
                    Math.round(el.scrollWidth) + ' px in ' +
                    parent.clientWidth + ' px');
    }
  }
  document.documentElement.setAttribute('data-probe', JSON.stringify({
    width: document.documentElement.scrollWidth,
    height: document.documentElement.scrollHeight, images: images,
    overflow: overflow}));
});
</script>
EOF
run_chromium --window-size="$width,800" --dump-dom \
  "$(file_url "$work/probe.html")" >"$work/dom.html" 2>"$work/probe.log"
probe="$(grep -o 'data-probe="[^"]*"' "$work/dom.html" | head -1 |
  sed -e 's/^data-probe="//' -e 's/"$//' -e 's/&quot;/"/g' -e 's/&amp;/\&/g')"
if [ -z "$probe" ]; then
  echo "screenshot_report: $page: the page did not finish loading in Chromium" >&2
  cat "$work/probe.log" >&2
  exit 1
fi
height="$(echo "$probe" | grep -o '"height":[0-9.]*' | head -1 | cut -d: -f2)"
height="${height%.*}"
run_chromium --window-size="$width,$height" --screenshot="$work/shot.png" \
  "$(file_url "$page")" >"$work/shot.log" 2>&1
[ -s "$work/shot.png" ] || {
  echo "screenshot_report: $page: Chromium wrote no screenshot" >&2
  cat "$work/shot.log" >&2
  exit 1
}
# Each output appears whole or not at all: written beside its final name, then renamed.
publish() { cp "$1" "$2.tmp.$$" && mv -f "$2.tmp.$$" "$2"; }
echo "$probe" >"$work/probe.json"
grep -h 'CONSOLE' "$work/probe.log" "$work/shot.log" >"$work/console.txt" || true
publish "$work/probe.json" "$out.json"
publish "$work/console.txt" "$out.console.txt"
publish "$work/shot.png" "$out"
echo "screenshot_report: wrote $out (${width}x$height)"
