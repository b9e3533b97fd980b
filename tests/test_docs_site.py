"""The documentation site's fast checks (the full build and the browser check are
``bash scripts/docs.sh``, which ``.ci/run`` calls after the suite).

* Every name of ``pointax.__all__`` has an entry in the API reference's pages.
* One source of help: ``pointax SUBCOMMAND --help`` and TPOINT's ``HELP`` print the
  text of ``pointax/data/help/*.md``, the files the site includes, without markup and
  with every entry whole.
"""

from __future__ import annotations

import argparse
import importlib.util
import io
import re
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
DOCS = REPO / "docs"


def _docs_extension():
    spec = importlib.util.spec_from_file_location("pointax_docs", DOCS / "_ext" / "pointax_docs.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _words(text: str) -> list[str]:
    return text.split()


# --------------------------------------------------------------------------- the API pages


def test_every_public_name_has_an_api_entry():
    import pointax

    rooms = _docs_extension().public_entries()
    entered = [name for entries in rooms.values() for name, _, _ in entries]
    assert sorted(entered) == sorted(pointax.__all__)
    assert len(entered) == len(set(entered))


@pytest.mark.slow  # imports every room (torch, dask): about 15 s
def test_api_pages_hold_a_directive_for_every_public_name(tmp_path):
    import pointax

    pages = _docs_extension().api_pages(tmp_path)
    text = "\n".join(p.read_text() for p in pages)
    for name in pointax.__all__:
        if name in pointax._SUBMODULES:
            assert f".. automodule:: pointax.{pointax._SUBMODULES[name]}\n" in text, name
        else:
            assert re.search(rf"^\.\. auto(class|function):: pointax\.{name}$|^\.\. py:data:: {name}\n   :module: pointax$",
                             text, flags=re.MULTILINE), name


# --------------------------------------------------------------------------- one source of help


def test_plain_removes_markdown_markup():
    from pointax.core.helptext import plain

    # The reference: each markup by hand.
    assert plain("`INDAT FILE`: read **a** run, see [the guide](x.md) and {func}`pointax.fit`.") == (
        "INDAT FILE: read a run, see the guide and pointax.fit."
    )
    assert plain("abs(value/sigma) >= 2 and *emphasis* but 2 * 3") == "abs(value/sigma) >= 2 and emphasis but 2 * 3"


def _subparsers():
    from pointax.cli import build_parser

    parser = build_parser()
    return next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices


def test_each_subcommand_help_prints_its_help_file(monkeypatch):
    from pointax.core.helptext import HELP_DIR, help_markdown, plain

    monkeypatch.setenv("COLUMNS", "90")
    choices = _subparsers()
    files = {p.stem for p in HELP_DIR.glob("*.md")} - {"tpoint_commands"}
    assert files <= set(choices), files - set(choices)
    for name in files:
        text = choices[name].format_help()
        assert "`" not in text and ":func:" not in text and "**" not in text, name
        # The description, whatever the filling, is the help file's text word for word.
        want = _words(plain(help_markdown(name)))
        got = _words(text)
        start = got.index(want[0])
        assert got[start : start + len(want)] == want, name
        for line in text.splitlines():
            assert len(line) <= 90, (name, line)


def test_every_subcommand_has_a_help_file():
    from pointax.core.helptext import HELP_DIR

    missing = [name for name in _subparsers() if not (HELP_DIR / f"{name}.md").is_file()]
    # Subcommands still being added may lack theirs: their parser's own description is used
    # (docs/cli.md shows it); the ones this project ships have files.
    assert not set(missing) & {"fit", "command", "fit-network", "centroid", "compare", "tpoint", "plot", "report", "plan"}


def _session_help(*words: str) -> str:
    from pointax.procedures import Runner, Session

    out = io.StringIO()
    session = Session(out=out)
    runner = Runner(session)
    runner.run_stream(io.StringIO("".join(f"HELP {w}\n" for w in words) or "HELP\n"), interactive=False)
    return out.getvalue()


def test_tpoint_help_prints_every_entry_whole_and_plain():
    from pointax.core.helptext import help_markdown, plain, tpoint_entries
    from pointax.procedures.parser import COMMANDS, GRAPHICS_NOT_DRAWN, NOT_IMPLEMENTED, NOTED_SETTINGS

    entries = tpoint_entries()
    described = {w for words, _ in entries for w in words}
    for word in (*COMMANDS, *NOTED_SETTINGS, *NOT_IMPLEMENTED, *GRAPHICS_NOT_DRAWN, "G..."):
        assert word in described, f"{word} has no entry in pointax/data/help/tpoint_commands.md"
    printed = _session_help()
    assert "`" not in printed and ":func:" not in printed and "**" not in printed
    # Every entry, word for word (the reference: the file's list items, markup removed by hand below).
    items = [item[2:] for item in re.split(r"\n(?=- `)", help_markdown("tpoint_commands").split("\n\n", 1)[-1].strip())]
    reference = [re.sub(r"`([^`]*)`", r"\1", " ".join(item.split())) for item in items]
    assert reference == [text for _, text in entries]
    assert _words(printed) == _words(" ".join(reference))
    for text in reference:
        assert text.endswith((".", ")")), f"an entry that does not end a sentence: {text}"
    assert plain(help_markdown("tpoint_commands")).count("INDAT FILE") == 1


def test_tpoint_help_for_one_word():
    printed = _session_help("FIT", "gsmap", "PLTE")
    assert printed.startswith("  FIT: one linearised (Gauss-Newton) adjustment")
    assert "  G...: draw TPOINT's named plot" in printed and "  CLRNG, PLTE," in printed


def test_the_site_includes_the_help_files():
    guide = (DOCS / "guides" / "tpoint_users.md").read_text()
    assert "```{include} ../../pointax/data/help/tpoint_commands.md" in guide
    extension = (DOCS / "_ext" / "pointax_docs.py").read_text()
    assert "help_markdown(name)" in extension  # docs/cli.md's commands page
    assert "{include} _generated/cli_page.md" in (DOCS / "cli.md").read_text()


def test_help_imports_no_numerical_library():
    import subprocess

    code = (
        "import sys\nfrom pointax.cli import main\n"
        "try:\n    main(['tpoint', '--help'])\nexcept SystemExit:\n    pass\n"
        "print('LOADED', sorted(m for m in ('jax', 'numpy', 'astropy', 'torch') if m in sys.modules))\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=REPO)
    assert proc.stdout.strip().splitlines()[-1] == "LOADED []", proc.stdout + proc.stderr
