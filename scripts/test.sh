#!/usr/bin/env bash
# Set up (idempotent) and run the whole test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
[ -f /usr/share/vulkan/icd.d/lvp_icd.json ] && export VK_ICD_FILENAMES=${VK_ICD_FILENAMES:-/usr/share/vulkan/icd.d/lvp_icd.json}
.venv/bin/ruff check --quiet .
# two workers (pytest-xdist), a test file per worker at a time: the suite's end-to-end
# tests are mostly single-threaded; PACT_TEST_WORKERS=0 runs it in one process. One
# math-library thread per process (unless set): two workers' torch and BLAS threads on
# two cores only wait on each other
export OMP_NUM_THREADS=${OMP_NUM_THREADS:-1} MKL_NUM_THREADS=${MKL_NUM_THREADS:-1}
exec .venv/bin/python -m pytest -q -n "${PACT_TEST_WORKERS:-2}" --dist loadfile "$@"
