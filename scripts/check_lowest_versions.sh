#!/usr/bin/env bash
# CI's second environment: pointax at the LOWEST versions pyproject.toml allows.
#
# Creates a throw-away virtual environment, installs pointax (with the plot extra) and
# pytest under the pins in scripts/lowest-versions.txt (pip constraints), checks that pip
# finds them consistent, then runs the README's `pointax fit` of the bundled run and a
# quick subset of the tests (fit, batch, shared, TPOINT files, masking, the command
# line). A failure here means a lower bound in pyproject.toml is wrong: raise it (and the
# pin) or fix the code.
#
# Usage: bash scripts/check_lowest_versions.sh [pytest arguments]   (default: the subset)
# scripts/setup.sh runs it when POINTAX_CHECK_LOWEST=1 (as .ci/run sets). PYTHON picks
# the interpreter (default python3, 3.11+); the environment is deleted afterwards unless
# POINTAX_LOWEST_VENV names a folder to keep it in.
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON="${PYTHON:-python3}"
start=$SECONDS
echo "== lowest versions: installing (scripts/lowest-versions.txt)"
if [ -n "${POINTAX_LOWEST_VENV:-}" ]; then
    venv="$POINTAX_LOWEST_VENV"
else
    venv="$(mktemp -d "${TMPDIR:-/tmp}/pointax-lowest.XXXXXX")"
    trap 'rm -rf "$venv"' EXIT
fi
[ -x "$venv/bin/python" ] || "$PYTHON" -m venv "$venv"
pip_install() { "$venv/bin/python" -m pip install --quiet --disable-pip-version-check "$@"; }
pip_install -c scripts/lowest-versions.txt ".[plot]" pytest pytest-xdist
"$venv/bin/python" -m pip check --disable-pip-version-check
# Bytecode for the dependencies (pip writes none under PYTHONDONTWRITEBYTECODE): see setup.sh.
"$venv/bin/python" -m compileall -q -j 0 "$("$venv/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')" >/dev/null 2>&1 || true
# Every pin must be what got installed (pip -c only constrains what something asks for).
"$venv/bin/python" - <<'PY'
import re, sys
from importlib.metadata import version
wrong = []
for line in open("scripts/lowest-versions.txt"):
    line = line.split("#")[0].strip()
    if line:
        name, want = re.split(r"==", line)
        got = version(name)
        print(f"   {name}=={got}")
        wrong += [f"{name}: pinned {want}, installed {got}"] if got != want else []
sys.exit("lowest versions not installed as pinned:\n" + "\n".join(wrong) if wrong else 0)
PY
echo "== lowest versions: installed in $((SECONDS - start)) s"
echo "== lowest versions: pointax fit of the bundled run"
# Outside the checkout, so that the installed package (not the source tree) is the one run.
(cd "$venv" && "$venv/bin/pointax" fit "$OLDPWD/examples/data/mmt_20210821.dat" --azimuth S-E)
echo "== lowest versions: quick test subset"
if [ $# -eq 0 ]; then
    set -- tests/test_fit.py tests/test_batch.py tests/test_shared.py tests/test_io_tpoint.py \
        tests/test_masking.py tests/test_cli.py
fi
"$venv/bin/python" -m pytest -q -p no:cacheprovider "$@"
echo "== lowest versions: passed in $((SECONDS - start)) s"
