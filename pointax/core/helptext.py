"""Help texts, one source for the command line, TPOINT's HELP and the documentation site.

The texts are Markdown files in ``pointax/data/help/``: ``<subcommand>.md`` is the
description ``pointax <subcommand> --help`` prints, ``tpoint_commands.md`` the entries
``HELP`` prints in ``pointax tpoint``. The site includes the same files (``docs/cli.md``,
``docs/guides/tpoint_users.md``); here they are read as plain text: inline code,
emphasis and links lose their markup, and paragraphs are filled to a width, never cut.

Plain Python, no numerical library (``pointax --help`` imports none).
"""

from __future__ import annotations

import re
import shutil
import textwrap
from pathlib import Path

__all__ = ["HELP_DIR", "plain", "help_markdown", "description", "tpoint_entries", "fill"]

HELP_DIR = Path(__file__).resolve().parent.parent / "data" / "help"
"""Where the help texts live (package data)."""

_LINK = re.compile(r"\[([^\]]+)\]\([^)]*\)")  # [text](target) -> text
_ROLE = re.compile(r"\{[a-z:]+\}`~?([^`]+)`")  # MyST roles: {func}`pointax.fit` -> pointax.fit
_CODE = re.compile(r"`([^`]+)`")
_STRONG = re.compile(r"\*\*([^*]+)\*\*")
_EMPH = re.compile(r"(?<![\w*])\*([^*\s][^*]*)\*(?![\w*])")


def plain(markdown: str) -> str:
    """``markdown`` without inline markup: ``` `x` ```, ``**x**``, ``*x*``, ``[x](url)``
    and MyST roles become ``x``; line breaks and paragraphs are kept."""
    text = _LINK.sub(r"\1", markdown)
    text = _ROLE.sub(r"\1", text)
    text = _CODE.sub(r"\1", text)
    text = _STRONG.sub(r"\1", text)
    return _EMPH.sub(r"\1", text)


def help_markdown(name: str) -> str:
    """The Markdown text of help file ``name`` (``fit``, ``tpoint_commands`` ...),
    without the HTML comments the site's sources may hold."""
    text = (HELP_DIR / f"{name}.md").read_text(encoding="utf-8")
    return re.sub(r"<!--.*?-->\s*", "", text, flags=re.DOTALL).strip()


def fill(paragraph: str, width: int, indent: str = "", subsequent: str | None = None) -> str:
    """One paragraph (or list item) filled to ``width`` columns at spaces."""
    return textwrap.fill(
        " ".join(paragraph.split()), width=width, initial_indent=indent,
        subsequent_indent=indent if subsequent is None else subsequent,
        break_long_words=False, break_on_hyphens=False,
    )


def _blocks(markdown: str) -> list[str]:
    """Paragraphs and list items of ``markdown`` (a list item is its own block)."""
    blocks: list[str] = []
    for para in re.split(r"\n\s*\n", markdown.strip()):
        items = re.split(r"\n(?=[*-] )", para)
        blocks.extend(item for item in items if item.strip())
    return blocks


def description(name: str, width: int | None = None) -> str:
    """The description of ``pointax <name> --help``: the help file as plain text,
    each paragraph filled to ``width`` columns (list items with a hanging indent);
    by default the terminal's width less 2, at most 88 (the width the options are filled to)."""
    if width is None:
        width = max(min(shutil.get_terminal_size().columns - 2, 88), 40)
    out = []
    for block in _blocks(plain(help_markdown(name))):
        if block[:2] in ("* ", "- "):
            out.append(fill(block[2:], width, indent="  * ", subsequent="    "))
        else:
            out.append(fill(block, width))
    return "\n\n".join(out)


def tpoint_entries() -> list[tuple[tuple[str, ...], str]]:
    """TPOINT's HELP, in the file's order: ``(words, text)`` per entry of
    ``tpoint_commands.md``, ``text`` plain. An entry is a list item that starts with
    its command in backticks (```` `INDAT FILE`: ... ````, or several,
    ```` `CLRNG`, `PLTE`: ... ````); its words are the first word of each."""
    entries = []
    for block in _blocks(help_markdown("tpoint_commands")):
        head = re.match(r"[*-] ((?:`[^`]+`(?:, )?)+):", block)
        if head:
            words = tuple(span.split()[0].upper() for span in re.findall(r"`([^`]+)`", head.group(1)))
            entries.append((words, " ".join(plain(block[2:]).split())))
    return entries
