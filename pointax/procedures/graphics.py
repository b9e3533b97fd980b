"""TPOINT's graphics commands in a session: G..., GC, CAPT and PLTZ.

* ``G y x``, ``GAM Z``, ``GSCAT [options]``, ``GSMAP``, ``GDIST``, ``A9`` ...: draw the
  named plot of the last FIT (:func:`pointax.plots.tpoint_graph`; the letters:
  :mod:`pointax.plots.tpoint_panels`). Options after a whole-plot word (``GSCAT A``) are
  TPOINT's display options: the plot is drawn, the options are noted. A TPOINT plot
  pointax does not draw (``GHYST``, a ``G y x`` with letters it does not read) gets a
  one-line note and the script goes on.
* ``PLTZ TL|TC|TR|CL|CC|CR|BL|BC|BR`` puts the following plots in that panel of a 3 x 3
  page (TPOINT's plot zones); ``PLTZ`` alone ends the page, which stays the current
  figure for GC.
* ``GC FILE``, ``GC B|P [FILE]`` write the current figure; ``GC`` alone keeps the
  current graphics device and writes nothing.
* ``CAPT ON|OFF`` shows or hides the caption on plots; ``CAPT TEXT`` sets the caption
  (model files and plots); ``CAPT "ON"`` (quoted) is a caption.
"""

from __future__ import annotations

from .parser import GRAPHICS_NOT_DRAWN, Line, Quoted
from .session import Session

__all__ = ["ZONES", "GC_DEVICES", "cmd_graph", "cmd_gc", "cmd_capt", "cmd_pltz", "require_fit"]

ZONES = {
    "TL": (0, 0), "TC": (0, 1), "TR": (0, 2),
    "CL": (1, 0), "CC": (1, 1), "CR": (1, 2),
    "BL": (2, 0), "BC": (2, 1), "BR": (2, 2),
}  # fmt: skip
"""PLTZ's panels of a 3 x 3 page: top, centre, bottom row; left, centre, right column."""

GC_DEVICES = {"P": "colour PostScript", "B": "black-and-white PostScript"}
"""TPOINT's GC device letters (``GC P`` writes ``tpoint.ps``; ``GC P FILE``)."""

_SWITCHES = {"ON": True, "OFF": False}


def require_fit(s: Session, what: str):
    """The last FIT's result; ValueError naming ``what`` before any FIT."""
    if s.result is None:
        raise ValueError(f"{what} shows the residuals of the last FIT: FIT first")
    return s.result


def _plot_request(args: list[str]) -> tuple[str, list[str]]:
    """``(command, options)``: the plot a graphics line names, for
    :func:`pointax.plots.tpoint_panels.parse_command`, and the display options after a
    whole-plot word (``GSCAT A``: ``('GSCAT', ['A'])``), which pointax does not use."""
    from ..plots.tpoint_panels import WHOLE_PLOTS

    word, rest = args[0].upper(), list(args[1:])
    if word in WHOLE_PLOTS:
        return word, rest
    return " ".join([word, *rest]), []


def _looks_like_codes(args: list[str]) -> bool:
    """Whether ``G ...`` names a residual and a position by letters (a TPOINT plot
    pointax may not read) rather than being garbled."""
    rest = args[1:]
    return args[0].upper() == "G" and len(rest) == 2 and all(a.isalpha() and len(a) <= 2 for a in rest)


def _not_drawn(s: Session, command: str, args: list[str], err: ValueError) -> bool:
    """Say that a TPOINT plot is not drawn, when it is one; False for an unknown word."""
    word = args[0].upper()
    if word in GRAPHICS_NOT_DRAWN:
        s.say(f"{command.upper()}: {GRAPHICS_NOT_DRAWN[word]}: not drawn by pointax (skipped)")
        return True
    if _looks_like_codes(args):
        s.say(f"{command.upper()}: not drawn: {err}")
        return True
    return False


def _title(s: Session, result) -> str:
    """The caption line of a plot: the session's caption, N and Sky RMS."""
    from ..plots.residuals import title_of

    title = title_of(result)
    old = (getattr(result, "caption", "") or "").strip()
    if old and title.startswith(old):
        title = title[len(old) :].lstrip(" -")
    return f"{s.current_caption()} - {title}"


def cmd_graph(s: Session, args: list[str], line: Line) -> None:
    """G...: draw TPOINT's named plot of the last FIT (G S A, GAM Z, GSCAT A, GSMAP,
    GDIST, A9 ...), in the PLTZ panel when one is set; GC FILE writes it.

    ``args[0]`` is the graphics word itself (the runner passes it)."""
    from ..plots.tpoint_panels import parse_command

    command, options = _plot_request(args)
    try:
        parsed = parse_command(command)
    except ValueError as err:
        if _not_drawn(s, " ".join(args), args, err):
            return
        raise
    result = require_fit(s, "G")
    if s.zone is not None and parsed[0] not in ("A9", "E9"):
        _draw_in_zone(s, parsed, result)
        where = f" in panel {s.zone}"
    else:
        _draw_figure(s, command, result)
        where = " (a whole page: PLTZ panels hold single plots)" if s.zone is not None else ""
    ignored = f"; TPOINT options {' '.join(options)} not used" if options else ""
    s.say(f"{' '.join(args).upper()}: drawn{where}{ignored}")


def _draw_figure(s: Session, command: str, result) -> None:
    from ..plots import tpoint_graph

    fig = tpoint_graph(command, result, s.observations())
    fig.suptitle(_title(s, result) if s.show_caption else "")
    s.figure = fig


def _draw_in_zone(s: Session, parsed: tuple[str, ...], result) -> None:
    """Draw one plot in the current PLTZ panel of the page (a new page when none is open)."""
    from ..plots.data import residual_data
    from ..plots.tpoint_panels import draw_graph

    if s.page is None:
        s.page = _new_page()
    fig, axes = s.page
    row, col = ZONES[s.zone]
    ax = axes[row][col]
    ax.clear()
    ax.set_axis_on()
    draw_graph(ax, residual_data(result, s.observations(), None), parsed, legend=False)
    if s.show_caption:
        fig.suptitle(_title(s, result))
    s.figure = fig


def _new_page():
    """A 3 x 3 page of empty panels: ``(figure, axes)``."""
    from ..plots._mpl import new_figure

    fig = new_figure(15.0, 14.0)
    axes = fig.subplots(3, 3)
    for ax in axes.ravel():
        ax.set_axis_off()
    return fig, axes


def cmd_pltz(s: Session, args: list[str], line: Line) -> None:
    """PLTZ TL|TC|TR|CL|CC|CR|BL|BC|BR: draw the following plots in that panel of a
    3 x 3 page; PLTZ alone: whole pages again (the page drawn stays the figure GC writes)."""
    if not args:
        was_open = s.page is not None
        s.zone, s.page = None, None
        s.say("PLTZ: whole pages" + ("; the 3 x 3 page drawn is the current figure (GC writes it)" if was_open else ""))
        return
    zone = args[0].upper()
    if len(args) != 1 or zone not in ZONES:
        raise ValueError(f"takes one panel of {', '.join(ZONES)} (or nothing: whole pages), got {' '.join(args)}")
    s.zone = zone
    s.say(f"PLTZ: panel {zone}" + ("" if s.page is not None else " of a new 3 x 3 page"))


def cmd_gc(s: Session, args: list[str], line: Line) -> None:
    """GC FILE: write the current figure in the format of the extension (.png, .svg,
    .pdf; .ps and .eps give PostScript); TPOINT's GC P [FILE] and GC B [FILE] too
    (default file tpoint.ps; drawn in colour either way); GC alone keeps the current
    graphics device and writes nothing."""
    from ..plots import save_figure

    if not args:
        kept = f" ({s.device})" if s.device else ""
        s.say(f"GC: graphics device kept{kept}; nothing written (GC FILE or GC B|P [FILE] writes the plot)")
        return
    first = args[0]
    device = first.upper() if not isinstance(first, Quoted) and first.upper() in GC_DEVICES else None
    if device is not None:
        args = args[1:] or ["tpoint.ps"]
    if len(args) != 1:
        raise ValueError("takes one file name (or TPOINT's GC P [FILE], GC B [FILE], or nothing)")
    if s.figure is None:
        raise ValueError("GC: no figure yet (draw one with a G command, e.g. G S A)")
    note = " (GC B asks for black and white: pointax draws in colour)" if device == "B" else ""
    path = line.path(args[0])
    s.say(f"GC: {save_figure(s.figure, path)}{note}")
    s.device = str(path)


def cmd_capt(s: Session, args: list[str], line: Line) -> None:
    """CAPT ON|OFF: show or hide the caption on plots; CAPT TEXT: the caption of plots
    and of model files written from now on (CAPT "ON", quoted, is a caption; CAPT alone:
    the run's caption again)."""
    if len(args) == 1 and not isinstance(args[0], Quoted) and args[0].upper() in _SWITCHES:
        s.show_caption = _SWITCHES[args[0].upper()]
        s.say(f"CAPT {args[0].upper()}: captions on plots {'shown' if s.show_caption else 'hidden'}")
        return
    s.caption = " ".join(args) or None
    s.say(f"CAPT: {s.current_caption()}")
