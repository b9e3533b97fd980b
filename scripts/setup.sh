#!/usr/bin/env bash
# Set up pointax in ./.venv: a virtual environment with pointax (editable), its test
# tools and the vision extra. Safe to run again: it only installs what is missing.
#
# torch is installed first, pinned to 2.13.0: this machine's pip finds a local CPU
# build of exactly that version, while any other torch request pulls several GB of
# CUDA packages from the registry. pyproject.toml asks for torch>=2.4, which 2.13.0
# satisfies, so the later install keeps it.
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON="${PYTHON:-python3}"
if [ ! -x .venv/bin/python ]; then
    "$PYTHON" -m venv .venv
fi
pip_install() { .venv/bin/python -m pip install --quiet --disable-pip-version-check "$@"; }
if ! .venv/bin/python -c "import torch" 2>/dev/null; then
    pip_install "torch==2.13.0"
fi
pip_install -e ".[dev,vision]"
