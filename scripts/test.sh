#!/usr/bin/env bash
# Set up (idempotent), then run the whole test suite: core unit tests and tests in real QGIS.
# Exit code: pytest's.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh

export QT_QPA_PLATFORM=offscreen
export PYTHONPATH="$PWD:/usr/share/qgis/python/plugins${PYTHONPATH:+:$PYTHONPATH}"
# pyproj inside a venv looks for PROJ's data under the venv: point it at Debian's (geoid grids too).
export PROJ_DATA="${PROJ_DATA:-/usr/share/proj}" PROJ_LIB="${PROJ_LIB:-/usr/share/proj}"
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-$(mktemp -d)}"
# Keep QGIS's own settings and profiles away from the user's.
export QGIS_CUSTOM_CONFIG_PATH="${QGIS_CUSTOM_CONFIG_PATH:-$(mktemp -d)}"
exec .venv/bin/python -m pytest tests/unit tests/scenarios tests/qgis -q -p no:cacheprovider "$@" </dev/null
