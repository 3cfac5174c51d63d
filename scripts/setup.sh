#!/usr/bin/env bash
# Set up this checkout on a Debian machine: .venv/ with pinned packages (uv), and
# Mesa's lavapipe Vulkan driver from bookworm-backports when SAPIEN finds no render
# device and apt is usable. Idempotent: a second run only checks stamps (a few seconds).
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$(pwd)
VENV="$ROOT/.venv"
PY="$VENV/bin/python"
log() { printf '[setup] %s\n' "$*" >&2; }

# 1. uv (from PyPI) -------------------------------------------------------------
if ! command -v uv >/dev/null 2>&1; then
  log "installing uv from PyPI"
  python3 -m pip install --quiet --disable-pip-version-check uv
fi
UV=$(command -v uv || echo "python3 -m uv")

# 2. virtualenv with pinned packages ------------------------------------------------
if [ ! -x "$PY" ]; then
  log "creating $VENV"
  $UV venv --quiet --python "$(command -v python3)" "$VENV"
fi
stamp="$VENV/.pact-deps-$(cat requirements.lock pyproject.toml | sha256sum | cut -c1-16)"
if [ ! -f "$stamp" ]; then
  log "installing pinned packages (requirements.lock)"
  $UV pip install --quiet --python "$PY" -r requirements.lock
  $UV pip install --quiet --python "$PY" --no-deps -e .
  rm -f "$VENV"/.pact-deps-*
  touch "$stamp"
else
  log "packages up to date"
fi
# Bytecode of the installed packages, written once: with PYTHONDONTWRITEBYTECODE set (as
# on some CI machines) Python never caches it and every process compiles torch, SAPIEN
# and ManiSkill from source again (about 4 s more per process start on 2 cores).
if [ ! -f "$VENV/.pact-bytecode-${stamp##*-}" ]; then
  log "compiling the packages' bytecode (once)"
  "$PY" -m compileall -q -j 2 "$VENV"/lib/python3*/site-packages >/dev/null 2>&1 || true
  rm -f "$VENV"/.pact-bytecode-*
  touch "$VENV/.pact-bytecode-${stamp##*-}"
fi

# 3. Vulkan render device for SAPIEN cameras (physics works without one) ------------
ICD=/usr/share/vulkan/icd.d/lvp_icd.json
probe_render() {
  # SAPIEN needs Mesa >= 24.3 lavapipe on CPU machines.
  VK_ICD_FILENAMES=${VK_ICD_FILENAMES:-$( [ -f $ICD ] && echo $ICD )} \
    timeout 120 "$PY" -c "import sapien; sapien.render.RenderSystem()" >/dev/null 2>&1
}
if probe_render; then
  log "render device: ok"
elif [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1 && grep -q bookworm /etc/os-release 2>/dev/null; then
  log "no Vulkan render device: installing Mesa lavapipe from bookworm-backports"
  if ! grep -rqs bookworm-backports /etc/apt/sources.list /etc/apt/sources.list.d/; then
    echo "deb http://deb.debian.org/debian bookworm-backports main" > /etc/apt/sources.list.d/bookworm-backports.list
  fi
  export DEBIAN_FRONTEND=noninteractive
  if apt-get update -qq && apt-get install -y -qq -t bookworm-backports mesa-vulkan-drivers libvulkan1 >/dev/null; then
    if probe_render; then log "render device: lavapipe ok"; else log "WARNING: lavapipe installed but SAPIEN still finds no render device; previews and RGB observations will be skipped"; fi
  else
    log "WARNING: apt could not install lavapipe; previews and RGB observations will be skipped (physics is unaffected)"
  fi
else
  log "WARNING: no Vulkan render device and apt is not usable here (needs root on Debian bookworm);"
  log "         previews and RGB observations will be skipped (physics is unaffected)."
  log "         To enable: apt-get install -t bookworm-backports mesa-vulkan-drivers libvulkan1"
fi

# 4. Chromium for the gallery's browser tests (tests/test_gallery.py) ----------------
if [ -x /usr/bin/chromium ]; then
  log "chromium: ok"
elif [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
  log "installing Debian's chromium (headless screenshots of the gallery's 3D views)"
  export DEBIAN_FRONTEND=noninteractive
  apt_log=$(mktemp)
  if apt-get install -y -qq chromium >"$apt_log" 2>&1 \
     || { apt-get update -qq >>"$apt_log" 2>&1 && apt-get install -y -qq chromium >>"$apt_log" 2>&1; }; then
    log "chromium: installed"
  else
    tail -n 5 "$apt_log" >&2
    log "WARNING: apt could not install chromium; the gallery's browser tests will be skipped"
  fi
  rm -f "$apt_log"
else
  log "WARNING: no /usr/bin/chromium and apt is not usable here (needs root on Debian);"
  log "         the gallery's browser tests will be skipped. To enable: apt-get install -y chromium"
fi

# 5. three.js for the gallery's 3D view (npm registry; not kept in the repository) -----
THREE_VERSION=0.187.0
THREE_DIR=asset_pipeline/gallery/web/three
if [ -f "$THREE_DIR/VERSION" ] && [ "$(cat "$THREE_DIR/VERSION")" = "$THREE_VERSION" ]; then
  log "three.js $THREE_VERSION: ok"
elif command -v npm >/dev/null 2>&1; then
  tmp=$(mktemp -d)
  if (cd "$tmp" && npm pack "three@$THREE_VERSION" --silent >/dev/null 2>&1); then
    rm -rf "$THREE_DIR" && mkdir -p "$THREE_DIR"
    # the page's modules and the two GLTFLoader imports, in the package's own layout
    tar xzf "$tmp/three-$THREE_VERSION.tgz" -C "$THREE_DIR" --strip-components=1 \
      package/LICENSE package/build/three.module.js package/build/three.core.js \
      package/examples/jsm/loaders/GLTFLoader.js package/examples/jsm/controls/OrbitControls.js \
      package/examples/jsm/utils/BufferGeometryUtils.js package/examples/jsm/utils/SkeletonUtils.js
    echo "$THREE_VERSION" > "$THREE_DIR/VERSION"
    log "three.js $THREE_VERSION: installed in $THREE_DIR"
  else
    log "WARNING: npm could not fetch three@$THREE_VERSION; the gallery's 3D views will be missing"
  fi
  rm -rf "$tmp"
else
  log "WARNING: no npm; the gallery's 3D views will be missing (apt-get install -y npm)"
fi
