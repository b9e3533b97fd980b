"""docs/layout.md names every module of the package, and every module it names exists
(a module added, renamed or removed without its line there fails here)."""

from __future__ import annotations

import re
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
PACKAGE = REPO / "pointax"


def _documented() -> set[str]:
    """``room/.../module.py`` for every module docs/layout.md lists in its tree."""
    text = (REPO / "docs" / "layout.md").read_text()
    tree = text[text.index("    pointax/\n") : text.index("    benchmarks/")]
    found, folders = set(), []  # folders: (indent, name) from the room down
    for line in tree.splitlines()[1:]:
        if not line.strip() or line.strip().startswith("<!--"):
            continue
        indent = len(line) - len(line.lstrip())
        folders = [(i, name) for i, name in folders if i < indent]
        first = line.split()[0]
        if first.endswith("/"):
            folders.append((indent, first.rstrip("/")))
        # Several modules on a line (cli/'s), or a folder's modules in its description (paint/).
        for name in re.findall(r"\b([a-z_0-9]+\.py)\b", line):
            found.add("/".join([f for _, f in folders] + [name]))
    return found


def test_every_module_has_its_line_and_every_line_its_module():
    modules = {
        str(p.relative_to(PACKAGE))
        for p in PACKAGE.rglob("*.py")
        if "__pycache__" not in p.parts and p.name != "__init__.py"
    }
    documented = {m for m in _documented() if not m.endswith("__init__.py")}
    assert sorted(modules - documented) == [], "modules missing from docs/layout.md"
    assert sorted(documented - modules) == [], "docs/layout.md names modules that do not exist"
