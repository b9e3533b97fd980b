"""Writing a Figure to a file whose extension names the format.

PostScript (``.ps``) goes on a paper page (``ps.papersize``, letter unless changed;
``papertype`` overrides it) and is laid out to fit it: portrait when the figure fits
upright, landscape when it fits turned (a wide figure), else scaled down uniformly
(the drawing keeps its proportions, as a printer's "fit to page" would) in whichever
orientation shrinks it least, centred within a margin of :data:`MARGIN_IN` inches.
matplotlib alone centres the figure on the page whatever its size, so a figure wider
than the paper got a bounding box past the page's edges (``-198 234 810 558`` on
letter) and printed as its middle column only. EPS and PDF have no paper: their page
(bounding box, MediaBox) is the figure itself, so the drawing always lies on it.
"""

from __future__ import annotations

import dataclasses
import io
import math
import os
import re

__all__ = ["FORMATS", "MARGIN_IN", "PageLayout", "format_of", "page_layout", "paper_size", "save_figure"]

FORMATS = {
    ".png": ("png", "PNG image"),
    ".svg": ("svg", "SVG drawing"),
    ".pdf": ("pdf", "PDF document"),
    ".ps": ("ps", "PostScript (matplotlib's PS backend)"),
    ".eps": ("eps", "Encapsulated PostScript (matplotlib's PS backend)"),
}
"""Extension -> (matplotlib format, description)."""

MARGIN_IN = 0.25
"""Blank margin kept on every side of a PostScript page, inches."""


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


def paper_size(papertype: str | None = None) -> tuple[str, float, float]:
    """``(name, width, height)`` in inches (portrait) of a matplotlib paper type; ``None``
    means ``rcParams['ps.papersize']``.

    Raises:
        ValueError: an unknown paper type, or ``'figure'`` (which is no paper).
    """
    import matplotlib as mpl
    from matplotlib.backends.backend_ps import papersize

    name = (papertype if papertype is not None else mpl.rcParams["ps.papersize"]).lower()
    if name not in papersize:
        raise ValueError(f"unknown paper type {name!r}; use one of {', '.join(sorted(papersize))}")
    width, height = papersize[name]
    return name, float(width), float(height)


@dataclasses.dataclass(frozen=True)
class PageLayout:
    """Where a figure goes on a paper page (:func:`page_layout`), inches and points."""

    papertype: str
    paper: tuple[float, float]
    """Paper width and height, inches, as the paper stands (portrait)."""
    orientation: str
    """``'portrait'`` or ``'landscape'`` (the figure turned a quarter counter-clockwise)."""
    scale: float
    """Drawing size / figure size (1 when the figure fits as it is)."""
    bbox: tuple[float, float, float, float]
    """The drawing's box on the page, PostScript points ``(llx, lly, urx, ury)``."""


def page_layout(size_in: tuple[float, float], papertype: str | None = None, margin: float = MARGIN_IN) -> PageLayout:
    """The layout of a ``(width, height)``-inch figure on a paper page: portrait when
    it fits within the margins upright, else landscape when it fits turned, else the
    orientation that needs the lesser shrinking, scaled to fit; centred."""
    name, pw, ph = paper_size(papertype)
    w, h = (float(x) for x in size_in)
    if not (w > 0 and h > 0):
        raise ValueError(f"figure size {w} x {h} in: both must be positive")
    room_w, room_h = pw - 2 * margin, ph - 2 * margin
    portrait = min(1.0, room_w / w, room_h / h)
    landscape = min(1.0, room_h / w, room_w / h)
    orientation = "portrait" if portrait >= 1.0 or portrait >= landscape else "landscape"
    scale = portrait if orientation == "portrait" else landscape
    dw, dh = 72 * scale * w, 72 * scale * h  # drawing, points, as drawn (before turning)
    if orientation == "landscape":
        dw, dh = dh, dw  # on the page
    llx, lly = (72 * pw - dw) / 2, (72 * ph - dh) / 2
    return PageLayout(name, (pw, ph), orientation, scale, (llx, lly, llx + dw, lly + dh))


_TRANSLATE = re.compile(r"^(\S+) (\S+) translate$", re.M)
_RECTCLIP = re.compile(r"^0 0 \S+ \S+ rectclip$", re.M)
_BBOX = re.compile(r"^%%BoundingBox: .*$", re.M)
_HIRES = re.compile(r"^%%HiResBoundingBox: .*$", re.M)


def _num(x: float) -> str:
    return f"{x:.6f}".rstrip("0").rstrip(".")


def _scaled_postscript(text: str, layout: PageLayout) -> str | None:
    """matplotlib's PostScript ``text`` (written for ``layout``'s paper and orientation
    at full size) with the figure scaled by ``layout.scale`` and centred; None when the
    text does not have the lines this expects (another matplotlib layout)."""
    page = text.find("%%Page: 1 1")
    if page < 0:
        return None
    translate = _TRANSLATE.search(text, page)
    clip = _RECTCLIP.search(text, page)
    if translate is None or clip is None or not translate.end() < clip.start():
        return None
    s = _num(layout.scale)  # the scale as written, and the box it gives
    pw, ph = (72 * x for x in layout.paper)
    llx, lly, urx, ury = layout.bbox
    dw, dh = urx - llx, ury - lly
    if layout.scale != float(s):
        dw, dh = dw * float(s) / layout.scale, dh * float(s) / layout.scale
    llx, lly, urx, ury = (pw - dw) / 2, (ph - dh) / 2, (pw + dw) / 2, (ph + dh) / 2
    if layout.orientation == "landscape":
        x0, y0 = urx, lly  # the figure's origin after a quarter turn counter-clockwise
    else:
        x0, y0 = llx, lly
    out = (
        text[: translate.start()]
        + f"{x0!r} {y0!r} translate"
        + text[translate.end() : clip.start()]
        + f"{s} {s} scale\n"
        + text[clip.start() :]
    )
    header = (
        f"%%BoundingBox: {int(math.floor(llx))} {int(math.floor(lly))} {int(math.ceil(urx))} {int(math.ceil(ury))}"
    )
    out = _BBOX.sub(header, out, count=1)
    return _HIRES.sub(f"%%HiResBoundingBox: {llx:.6f} {lly:.6f} {urx:.6f} {ury:.6f}", out, count=1)


def _save_postscript(fig, name: str, papertype: str | None) -> PageLayout:
    """Write ``fig`` as PostScript on a paper page, laid out by :func:`page_layout`."""
    import matplotlib as mpl

    layout = page_layout(tuple(fig.get_size_inches()), papertype)
    options = {"format": "ps", "papertype": layout.papertype, "orientation": layout.orientation}
    if layout.scale >= 1.0:
        fig.savefig(name, **options)
        return layout
    buffer = io.StringIO()
    with mpl.rc_context({"ps.usedistiller": None}):  # the text below is matplotlib's own
        fig.savefig(buffer, **options)
    text = _scaled_postscript(buffer.getvalue(), layout)
    if text is not None:
        with open(name, "w", encoding="latin-1", newline="") as fh:
            fh.write(text)
        return layout
    # Not the PostScript this module knows (e.g. text.usetex): shrink the figure itself
    # to the page instead (its text keeps its point size, so the layout is redone).
    size = fig.get_size_inches().copy()
    try:
        fig.set_size_inches(size * layout.scale)
        fig.savefig(name, **options)
    finally:
        fig.set_size_inches(size)
    return page_layout(tuple(size * layout.scale), layout.papertype)


def save_figure(fig, path: str | os.PathLike, *, dpi: int = 120, papertype: str | None = None) -> str:
    """Write ``fig`` to ``path`` in the format its extension names: ``.png`` (``dpi``
    dots per inch), ``.svg``, ``.pdf``, ``.eps``, or ``.ps`` (PostScript on a
    ``papertype`` page, default ``rcParams['ps.papersize']``; portrait, landscape or
    scaled so that the drawing fits the page: see :mod:`pointax.plots.save`). Returns a
    short description of what was written, e.g. ``'PNG image, 1680 x 840 px, 143 kB:
    fit.png'`` or ``'PostScript (...), letter landscape at 66%, 80 kB: fit.ps'``.

    Raises:
        ValueError: an unknown extension or paper type (before anything is written).
        OSError: the file cannot be written.
    """
    fmt, description = format_of(path)
    name = os.fspath(path)
    detail = ""
    if fmt == "ps":
        layout = _save_postscript(fig, name, papertype)
        detail = f", {layout.papertype} {layout.orientation}"
        if layout.scale < 1.0:
            detail += f" at {100 * layout.scale:.0f}%"
    else:
        fig.savefig(name, format=fmt, dpi=dpi)
    size = os.path.getsize(name)
    if fmt == "png":
        w, h = fig.get_size_inches() * dpi
        detail = f", {int(round(w))} x {int(round(h))} px"
    return f"{description}{detail}, {size / 1024:.0f} kB: {name}"
