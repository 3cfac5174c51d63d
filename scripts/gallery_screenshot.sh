#!/usr/bin/env bash
# Screenshot an output folder's gallery with headless Chromium.
#   scripts/gallery_screenshot.sh OUT [PNG]      (PNG defaults to OUT/gallery.png)
# Writes OUT/index.html first when it is missing. Serves OUT on 127.0.0.1 (a free port)
# for the time of the shot, since 3D views cannot load from a file:// page, and waits
# until the page says its 3D views in sight have drawn (at most TIMEOUT seconds).
# Nothing leaves the machine: Chromium runs with a new empty profile and no background
# networking (`python -m asset_pipeline.gallery.server --help`, --screenshot).
# Environment:
#   WIDTH, HEIGHT   window size (default 1280 x 2000)
#   QUERY           page query, e.g. 'asset=cab_a&q=joint_door_0:upper' (that asset's 3D
#                   view full-window with the door open; see asset_pipeline/gallery/web/viewer.js)
#   TIMEOUT         seconds to wait for the 3D views (default 60)
#   CHROMIUM        browser binary (default /usr/bin/chromium; Debian: apt-get install -y chromium)
# Exit status: 0 shot taken, 4 shot taken but the page was not ready (a 3D view failed
# or timed out), 3 no Chromium, 1 other failures.
set -euo pipefail
if [ $# -lt 1 ] || [ $# -gt 2 ]; then
  echo "usage: $0 OUT [PNG]" >&2
  exit 2
fi
out=$(cd "$1" && pwd)
png=${2:-$out/gallery.png}
case "$png" in /*) ;; *) png="$(pwd)/$png" ;; esac
repo=$(cd "$(dirname "$0")/.." && pwd)
python=${PYTHON:-$repo/.venv/bin/python}
chromium=${CHROMIUM:-/usr/bin/chromium}
if [ ! -x "$chromium" ]; then
  echo "error: $chromium not found; install it with: apt-get install -y chromium" >&2
  exit 3
fi
cd "$repo"
exec env CHROMIUM="$chromium" "$python" -m asset_pipeline.gallery.server "$out" --no-write \
  --screenshot "$png" --query "${QUERY:-}" --width "${WIDTH:-1280}" --height "${HEIGHT:-2000}" \
  --timeout "${TIMEOUT:-60}"
