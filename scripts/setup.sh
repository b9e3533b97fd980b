#!/usr/bin/env bash
# Set up pointax in ./.venv: a virtual environment with pointax (editable), its test
# tools, the vision and plot extras, and Debian's chromium (for the report's check).
# Safe to run again: it only installs what is missing.
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
pip_install -e ".[dev,vision,plot,docs]"  # docs: the site, bash scripts/docs.sh
# Byte-compile the package and its dependencies, as a regular install does: where Python
# may not write bytecode itself (PYTHONDONTWRITEBYTECODE, with which pip compiles nothing
# either), every process would otherwise compile JAX, NumPy and pointax from source
# (`import jax` 2.1 s instead of 0.7 s, in every command and every test subprocess).
.venv/bin/python -m compileall -q -j 0 pointax "$(.venv/bin/python -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')" >/dev/null 2>&1 || true
# Headless Chromium (Debian's package) renders the HTML report in tests/test_report.py;
# best effort: where apt-get cannot install it (not root, no Debian), that test skips.
if ! command -v chromium >/dev/null 2>&1 && command -v apt-get >/dev/null 2>&1 && [ "$(id -u)" = 0 ]; then
    (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends chromium) \
        >/dev/null 2>&1 || echo "setup.sh: could not install chromium; the report's browser check will skip" >&2
fi
# CI's second environment (.ci/run sets POINTAX_CHECK_LOWEST=1): pointax at the lowest
# versions pyproject.toml allows, in a throw-away venv, with a quick subset of the tests
# (scripts/check_lowest_versions.sh; about 5 minutes). Users' set-ups skip it.
if [ "${POINTAX_CHECK_LOWEST:-0}" = 1 ]; then
    PYTHON="$PYTHON" bash scripts/check_lowest_versions.sh
fi
