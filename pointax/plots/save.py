"""Writing a Figure to a file whose extension names the format."""

from __future__ import annotations

import os

__all__ = ["FORMATS", "save_figure", "format_of"]

FORMATS = {
    ".png": ("png", "PNG image"),
    ".svg": ("svg", "SVG drawing"),
    ".pdf": ("pdf", "PDF document"),
    ".ps": ("ps", "PostScript (matplotlib's PS backend)"),
    ".eps": ("eps", "Encapsulated PostScript (matplotlib's PS backend)"),
}
"""Extension -> (matplotlib format, description)."""


def format_of(path: str | os.PathLike) -> tuple[str, str]:
    """``(matplotlib format, description)`` for a file name's extension (any case).

    Raises:
        ValueError: an extension not in :data:`FORMATS`.
    """
    ext = os.path.splitext(os.fspath(path))[1].lower()
    if ext not in FORMATS:
        raise ValueError(
            f"{os.fspath(path)}: cannot tell the graphics format from the extension {ext or '(none)'!r}; "
            f"use one of {', '.join(FORMATS)}"
        )
    return FORMATS[ext]


def save_figure(fig, path: str | os.PathLike, *, dpi: int = 120) -> str:
    """Write ``fig`` to ``path`` in the format its extension names: ``.png`` (``dpi``
    dots per inch), ``.svg``, ``.pdf``, or ``.ps`` / ``.eps`` (PostScript, written by
    matplotlib's own PS backend). Returns a short description of what was written,
    e.g. ``'PNG image, 1680 x 840 px, 143 kB: fit.png'``.

    Raises:
        ValueError: an unknown extension (before anything is written).
        OSError: the file cannot be written.
    """
    fmt, description = format_of(path)
    name = os.fspath(path)
    fig.savefig(name, format=fmt, dpi=dpi)
    size = os.path.getsize(name)
    detail = ""
    if fmt == "png":
        w, h = fig.get_size_inches() * dpi
        detail = f", {int(round(w))} x {int(round(h))} px"
    return f"{description}{detail}, {size / 1024:.0f} kB: {name}"
