#!/usr/bin/env bash
# Idempotent set-up: Debian packages (installed only when missing) and the .venv with pytest-qgis and ruff.
set -euo pipefail
cd "$(dirname "$0")/.."

PACKAGES=(qgis python3-qgis qgis-providers python3-gdal gdal-bin python3-pyproj python3-scipy python3-matplotlib python3-pytest proj-data python3-distributed xvfb xauth)
missing=()
for p in "${PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
    echo "setup: installing ${missing[*]}"
    SUDO=""
    [ "$(id -u)" -eq 0 ] || SUDO="sudo"
    export DEBIAN_FRONTEND=noninteractive
    $SUDO apt-get update -q </dev/null
    $SUDO apt-get install -y -q --no-install-recommends "${missing[@]}" </dev/null
fi

if [ ! -x .venv/bin/python ]; then
    /usr/bin/python3 -m venv --system-site-packages .venv
fi
if ! .venv/bin/python -c "import pytest_qgis" 2>/dev/null; then
    .venv/bin/python -m pip install -q --disable-pip-version-check "pytest-qgis<3" </dev/null
fi
RUFF_VERSION=0.17.5  # the linter .ci/run runs (configuration: ruff.toml)
if [ "$(.venv/bin/ruff --version 2>/dev/null)" != "ruff $RUFF_VERSION" ]; then
    .venv/bin/python -m pip install -q --disable-pip-version-check "ruff==$RUFF_VERSION" </dev/null
fi
