#!/usr/bin/env bash
# Screenshot an output folder's gallery with headless Chromium.
#   scripts/gallery_screenshot.sh OUT [PNG]      (PNG defaults to OUT/gallery.png)
# Writes OUT/index.html first when it is missing. Needs /usr/bin/chromium
# (Debian: apt-get install -y chromium). WIDTH and HEIGHT override the window size.
set -euo pipefail
if [ $# -lt 1 ] || [ $# -gt 2 ]; then
  echo "usage: $0 OUT [PNG]" >&2
  exit 2
fi
out=$(cd "$1" && pwd)
png=${2:-$out/gallery.png}
repo=$(cd "$(dirname "$0")/.." && pwd)
python=${PYTHON:-$repo/.venv/bin/python}
chromium=${CHROMIUM:-/usr/bin/chromium}
if [ ! -x "$chromium" ]; then
  echo "error: $chromium not found; install it with: apt-get install -y chromium" >&2
  exit 3
fi
if [ ! -f "$out/index.html" ]; then
  (cd "$repo" && "$python" -c 'import sys; from asset_pipeline.gallery import write_gallery; write_gallery(sys.argv[1])' "$out")
fi
profile=$(mktemp -d)
trap 'rm -rf "$profile"' EXIT
tmp_png="$profile/shot.png"
"$chromium" --headless --no-sandbox --disable-gpu --disable-quic --no-first-run \
  --disable-background-networking --disable-component-update --disable-sync \
  --user-data-dir="$profile/profile" --hide-scrollbars \
  --window-size="${WIDTH:-1280},${HEIGHT:-2000}" --screenshot="$tmp_png" \
  "file://$out/index.html" >"$profile/chromium.log" 2>&1 || {
    cat "$profile/chromium.log" >&2
    echo "error: chromium failed" >&2
    exit 1
  }
if [ ! -s "$tmp_png" ]; then
  cat "$profile/chromium.log" >&2
  echo "error: chromium wrote no screenshot" >&2
  exit 1
fi
mv "$tmp_png" "$png"
echo "$png"
