#!/usr/bin/env bash
# Build the documentation site into docs/_build/html/ (warnings are errors), then open
# every page in headless Chromium (docs/_scripts/check_site.py): a broken internal link,
# a missing image or a console error fails; screenshots of the home page, one API page
# and one guide go to docs/_build/screenshots/. Installs the docs extra into ./.venv
# when Sphinx is missing (run scripts/setup.sh first). Open docs/_build/html/index.html.
#
# The examples run at their build-time size (POINTAX_DOCS_QUICK=1, set by docs/conf.py);
# sphinx-gallery keeps their output between builds until an example changes
# (docs/_ext/pointax_docs.py). DOCS_CLEAN=1 starts from nothing; DOCS_NO_BROWSER=1 skips
# the browser check (no chromium).
set -euo pipefail
cd "$(dirname "$0")/.."
PY=.venv/bin/python
if ! "$PY" -c "import sphinx, furo, myst_parser, sphinx_gallery, sphinx_copybutton" 2>/dev/null; then
    "$PY" -m pip install --quiet --disable-pip-version-check -e ".[docs]"
fi
if [ "${DOCS_CLEAN:-0}" = 1 ]; then
    rm -rf docs/_build docs/_generated docs/api/generated docs/auto_examples
fi
start=$(date +%s)
# A fresh html folder each time (no page of an earlier build left behind); the parsed
# sources stay cached in docs/_build/doctrees.
rm -rf docs/_build/html
"$PY" -m sphinx -b html -W --keep-going -q -d docs/_build/doctrees docs docs/_build/html
echo "docs.sh: site built in $(( $(date +%s) - start )) s: docs/_build/html/index.html"
if [ "${DOCS_NO_BROWSER:-0}" = 1 ]; then
    echo "docs.sh: browser check skipped (DOCS_NO_BROWSER=1)"
else
    "$PY" docs/_scripts/check_site.py docs/_build/html docs/_build/screenshots
fi
