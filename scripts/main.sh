#!/usr/bin/env bash
# Set up (idempotent) and run the main job on the bundled examples:
# convert examples/images/ into validated sim assets in out/examples/, then write the gallery.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
[ -f /usr/share/vulkan/icd.d/lvp_icd.json ] && export VK_ICD_FILENAMES=${VK_ICD_FILENAMES:-/usr/share/vulkan/icd.d/lvp_icd.json}
OUT=${1:-out/examples}
status=0
.venv/bin/pact convert examples/images --out "$OUT" "${@:2}" || status=$?
.venv/bin/pact gallery "$OUT" >/dev/null
echo
echo "assets:   $OUT/<id>/ (model.urdf, model.xml, report.json, preview.png)"
echo "catalog:  $OUT/registry.sqlite   (.venv/bin/pact ls $OUT)"
echo "gallery:  .venv/bin/pact gallery $OUT --serve, then open http://127.0.0.1:8000/"
exit $status
