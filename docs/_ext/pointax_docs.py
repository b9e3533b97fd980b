"""Pages the site generates before Sphinx reads its sources (conf.py loads this).

* ``docs/api/<room>.rst``: the API reference, one page per room, an entry for every
  name of ``pointax.__all__`` (its room from ``pointax._EXPORTS`` / ``_SUBMODULES``),
  so that a public name added to the package is documented without editing the docs.
* ``docs/_generated/cli/<name>.txt``: each subcommand's usage and options exactly as
  ``pointax <name> --help`` prints them (88 columns); the description above them on
  the site is ``pointax/data/help/<name>.md``, the text ``--help`` prints too.
* ``docs/_generated/conventions.png``: the conventions figure
  (``docs/_scripts/conventions_figure.py``).
* Gallery cache: an executed example is kept between builds (sphinx-gallery skips a
  gallery script it has run) until the file of ``examples/`` it runs changes.
"""

from __future__ import annotations

import hashlib
import inspect
import json
import os
import re
import runpy
from pathlib import Path

DOCS = Path(__file__).resolve().parent.parent
REPO = DOCS.parent

ROOM_TITLES = {
    "core": ("Models, mounts and observations", "The forward model: mounts, models, observations, the inverse, simulation and units (``pointax/core/``)."),
    "terms": ("Error terms and model factories", "The term library and the factories that put a mount and its terms together (``pointax/terms/``)."),
    "fitting": ("Fitting", "Every fit: solo, batched, shared-parameter and leave-one-out, with TPOINT's statistics (``pointax/fitting/``)."),
    "sky": ("Sun and stars", "The astropy edge: topocentric sun directions, sites, the bright-star catalogue (``pointax/sky/``)."),
    "io": ("File formats", "Readers and writers of every format pointax knows (``pointax/io/``); see also :doc:`/formats/index`."),
    "plots": ("Figures", "matplotlib figures and the HTML report (``pointax/plots/``)."),
    "planning": ("Planning a run", "Plans of the next pointing run and their predicted accuracy (``pointax/planning/``)."),
    "analysis": ("Analysis", "Model comparison, FAUTO, model building, networks and heliostats (``pointax/analysis/``)."),
    "procedures": ("TPOINT procedures", "TPOINT's command language (``pointax/procedures/``)."),
    "sunsensor": ("Sun-sensor images", "The torch/kornia edge: sun-sensor frames, centroids, cameras (``pointax/sunsensor/``)."),
}
"""Title and one-line introduction of each room's API page (a room not listed gets its name)."""

EXTRA_MODULES = {"plots": ["pointax.plots"], "procedures": ["pointax.procedures"], "sunsensor": ["pointax.sunsensor"]}
"""Rooms whose public names are not top-level names of pointax: documented as modules."""


def public_entries() -> dict[str, list[tuple[str, str, str]]]:
    """room -> ``[(public name, kind, target)]`` for every name of ``pointax.__all__``:
    kind ``module`` (target: the module's real dotted name) or ``object``
    (target: ``pointax.NAME``)."""
    import pointax

    rooms: dict[str, list[tuple[str, str, str]]] = {}
    for name in pointax.__all__:
        if name in pointax._SUBMODULES:
            module = pointax._SUBMODULES[name]
            entry = (name, "module", f"pointax.{module}")
        elif name in pointax._EXPORTS:
            module = pointax._EXPORTS[name]
            entry = (name, "object", f"pointax.{name}")
        else:
            raise RuntimeError(f"pointax.__all__ names {name!r}, which neither _EXPORTS nor _SUBMODULES maps")
        rooms.setdefault(module.split(".")[0], []).append(entry)
    return rooms


def _directive(name: str, kind: str, target: str, seen: set[int]) -> list[str]:
    """The reST of one public name's entry. ``seen``: ids of the classes and functions
    already documented (a module's members that are documented elsewhere are listed,
    not documented twice: Sphinx refuses two descriptions of one object)."""
    import importlib
    import pprint

    import pointax

    if kind == "module":
        alias = "" if target == f"pointax.{name}" else f" (``px.{name}``)"
        title = f"``{target}``{alias}"
        module = importlib.import_module(target)
        members = list(getattr(module, "__all__", []))
        again = [m for m in members if id(getattr(module, m, None)) in seen]
        lines = [title, "-" * len(title), "", f".. automodule:: {target}", "   :members:"]
        if again:
            lines.append(f"   :exclude-members: {', '.join(again)}")
        lines.append("")
        if again:
            lines += [f"Also in this module, each documented as a name of ``pointax``: {', '.join(f'``{m}``' for m in again)}.", ""]
        seen.update(id(getattr(module, m)) for m in members if callable(getattr(module, m, None)))
        return lines
    obj = getattr(pointax, name)
    title = f"``px.{name}``"
    head = [title, "-" * len(title), ""]
    if callable(obj):
        seen.add(id(obj))
        if inspect.isclass(obj):
            return head + [f".. autoclass:: {target}", "   :members:", ""]
        return head + [f".. autofunction:: {target}", ""]
    # A constant: its value (its module's comments say what it is).
    value = pprint.pformat(obj, width=84, compact=True).splitlines()
    return head + [f".. py:data:: {name}", "   :module: pointax", "", f"   Defined in ``{pointax._EXPORTS[name]}``; its value::", ""] + [
        "      " + line for line in value[:40]] + ([f"      ... ({len(value) - 40} more lines)"] if len(value) > 40 else []) + [""]


def api_pages(out: Path) -> list[Path]:
    """Write the API reference's room pages into ``out``; returns the files written."""
    out.mkdir(parents=True, exist_ok=True)
    written = []
    rooms = public_entries()
    for room, modules in EXTRA_MODULES.items():
        rooms.setdefault(room, []).extend((m.removeprefix("pointax."), "module", m) for m in modules)
    import pointax

    # Names documented as themselves: a module's members that are one of them are
    # listed in the module's entry, not described twice.
    seen = {id(getattr(pointax, n)) for n in pointax.__all__ if n in pointax._EXPORTS and callable(getattr(pointax, n))}
    order = list(ROOM_TITLES) + sorted(set(rooms) - set(ROOM_TITLES))
    for k, room in enumerate(r for r in order if r in rooms):
        title, intro = ROOM_TITLES.get(room, (room, f"``pointax/{room}/``"))
        lines = [".. This page is generated by docs/_ext/pointax_docs.py from pointax.__all__; do not edit.", ""]
        lines += [title, "=" * len(title), "", intro, ""]
        for name, kind, target in rooms[room]:
            lines += _directive(name, kind, target, seen)
        path = out / f"{k:02d}_{room}.rst"
        text = "\n".join(lines)
        if not path.exists() or path.read_text() != text:  # unchanged pages keep their time: no rebuild
            path.write_text(text)
        written.append(path)
    for stale in set(out.glob("*.rst")) - set(written):
        stale.unlink()
    return written


def cli_options(out: Path) -> list[Path]:
    """Each subcommand's usage and options, as its ``--help`` prints them at 88 columns."""
    from pointax.cli import build_parser

    out.mkdir(parents=True, exist_ok=True)
    old = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = "90"  # argparse fills at COLUMNS - 2
    try:
        parser = build_parser()
        sub = next(a for a in parser._actions if a.dest == "command")  # argparse's subparsers action
        written = []
        for name, p in sub.choices.items():
            p.description = None
            path = out / f"{name}.txt"
            path.write_text(p.format_help())
            written.append(path)
    finally:
        if old is None:
            os.environ.pop("COLUMNS", None)
        else:
            os.environ["COLUMNS"] = old
    return written


def cli_page(options: Path, out: Path) -> Path:
    """The commands' page (included by docs/cli.md): per subcommand, its description
    (``pointax/data/help/<name>.md``, the text its ``--help`` prints) and its options
    (``options/<name>.txt``)."""
    from pointax.cli import build_parser
    from pointax.core.helptext import HELP_DIR, help_markdown

    sub = next(a for a in build_parser()._actions if a.dest == "command")
    lines = []
    for name, p in sub.choices.items():
        lines += [f"## `pointax {name}`", ""]
        if (HELP_DIR / f"{name}.md").is_file():
            lines += [help_markdown(name), ""]
        elif p.description:
            lines += [p.description, ""]
        lines += ["```text", (options / f"{name}.txt").read_text().rstrip(), "```", ""]
    out.write_text("\n".join(lines))
    return out


def conventions_figure(out: Path) -> Path:
    """The conventions figure, drawn by docs/_scripts/conventions_figure.py."""
    out.mkdir(parents=True, exist_ok=True)
    path = out / "conventions.png"
    script = DOCS / "_scripts" / "conventions_figure.py"
    if not path.exists() or path.stat().st_mtime < script.stat().st_mtime:
        runpy.run_path(str(script))["main"](path)
    return path


def gallery_cache(gallery: Path, built: Path) -> None:
    """Forget sphinx-gallery's record of a gallery script whose example changed.

    Each ``plot_*.py`` names the example it runs in a line ``# example: examples/X.py``;
    sphinx-gallery re-runs a script only when the script itself changes, so the
    example's hash is kept beside its output and a change removes the script's
    ``.md5`` record (the script then runs again)."""
    record = built / "example_hashes.json"
    old = json.loads(record.read_text()) if record.exists() else {}
    new = {}
    for script in sorted(gallery.glob("plot_*.py")):
        names = [line.split(":", 1)[1].strip() for line in script.read_text().splitlines() if line.startswith("# example:")]
        digest = hashlib.sha256(b"".join((REPO / n).read_bytes() for n in names)).hexdigest()
        new[script.name] = digest
        if old.get(script.name) != digest:
            for stale in built.glob(f"{script.stem}.py.md5"):
                stale.unlink()
    built.mkdir(parents=True, exist_ok=True)
    record.write_text(json.dumps(new, indent=1))


_LITERAL = re.compile(r"``.*?``|`[^`]*`")


def _escape_outside_literals(line: str) -> str:
    """``|`` and a ``*`` that opens no emphasis (``*batch``, ``2*pi``) escaped, outside
    inline literals and roles: plain text in docstrings that reST would misread."""
    out, last = [], 0
    for m in _LITERAL.finditer(line):
        out.append(_escape(line[last : m.start()]))
        out.append(m.group(0))
        last = m.end()
    out.append(_escape(line[last:]))
    return "".join(out)


def _escape(text: str) -> str:
    text = re.sub(r"(?<!\\)\|", r"\\|", text)
    return re.sub(r"(?<![\\*])\*(?=\w)(?![^*]*\w\*(?!\w))", r"\\*", text)


def clean_docstring(app, what, name, obj, options, lines: list[str]) -> None:
    """Docstrings as reST reads them, changed only where reST would misread plain text
    (before napoleon): an indented example after a paragraph becomes a literal block,
    and ``|x|`` or ``*batch`` outside inline literals are escaped."""
    out: list[str] = []
    for k, line in enumerate(lines):
        stripped = line.strip()
        if not (line.startswith(("|", "+")) or stripped.startswith((".. ", ":"))):
            line = _escape_outside_literals(line)
        if (stripped and k >= 2 and not lines[k - 1].strip()
                and len(line) - len(line.lstrip()) > len(lines[k - 2]) - len(lines[k - 2].lstrip())):
            prev = lines[k - 2].rstrip()
            if prev and not prev.endswith(":") and not prev.lstrip().startswith(("* ", "- ", ".. ")) and out and out[-1] == "":
                out[-1:] = ["", "::", ""]
        out.append(line)
    lines[:] = out


def clean_types(app, what, name, obj, options, lines: list[str]) -> None:
    """After napoleon: the ``*`` of array shapes in the types it writes
    (``:type: Float[Array, '*batch 2']``) escaped, as plain text."""
    for k, line in enumerate(lines):
        if line.lstrip().startswith((":type:", ":rtype:", ":vartype")):
            lines[k] = re.sub(r"(?<!\\)\*", r"\\*", line)


def _generate(app) -> None:
    api_pages(DOCS / "api" / "generated")
    cli_options(DOCS / "_generated" / "cli")
    cli_page(DOCS / "_generated" / "cli", DOCS / "_generated" / "cli_page.md")
    conventions_figure(DOCS / "_generated")
    gallery_cache(DOCS / "gallery", DOCS / "auto_examples")


def setup(app):
    # "config-inited" runs before sphinx-gallery's "builder-inited" handler (which runs
    # the examples): the gallery cache must be cleared first.
    app.connect("config-inited", lambda app, config: _generate(app))
    app.connect("autodoc-process-docstring", clean_docstring, priority=400)  # before napoleon
    app.connect("autodoc-process-docstring", clean_types, priority=600)  # after napoleon
    return {"parallel_read_safe": True, "parallel_write_safe": True, "version": "1"}
