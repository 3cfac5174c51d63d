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
