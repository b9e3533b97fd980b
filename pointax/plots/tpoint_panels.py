"""TPOINT's graphics commands by name, and its nine-panel alt-az set (A9).

A plot command is ``G`` followed by what to plot (the ordinate, a residual) and what
to plot it against (the abscissa, a position), with or without spaces and in any
case: ``G S A``, ``gsa``, ``GAM Z``, ``G AM Z``. The codes, as pointax reads them. TPOINT's
own manual was not at hand to check every letter; each panel's title spells out what it
shows. What observatories' published TPOINT sessions confirm (JCMT's procedure page,
GBT's TPOINT summaries): the spaced form ``g s a``, ``g a a``, ``g z z``; dS as the
azimuth residual on the sky and dZ as the zenith-distance residual; A and Z as
positions; GSMAP, GSCAT and GDIST as commands; A9 run as a procedure (``call a9``) and an
equatorial counterpart E9. The other letters (E, V, R, D, X, H as residuals; E, H, D, N
as positions), GHIST, the panels of A9 beyond dS and dZ against A and Z, and all of E9's
panels are pointax's reading. TPOINT's GHYST (not drawn here) is not a histogram.

Residuals (ordinate), observed minus model, in the fit's unit (arcsec):

    S        dS = dA cos E: the cross-elevation residual (alt-az mounts: as the file
             counts azimuth; other mounts: along azimuth from North through East)
    A, AM    dA = dS / cos E: the azimuth residual itself
    E        dE: the elevation residual
    Z        dZ = -dE: the zenith-distance residual
    V, R     the on-sky distance sqrt(dS^2 + dE^2) (the R of MASK R > x)
    D        equatorial mounts: d dec; other mounts: the on-sky distance (as V)
    X        the mount's own cross-axis residual: dA cos E on alt-az mounts (as S; the
             dX of ``pointax fit --list``), dH cos dec (cross-declination) on equatorial ones
    H        equatorial mounts: dH = dX / cos dec

Positions (abscissa), of the observed (catalogue) direction, degrees:

    A        azimuth (alt-az mounts: as the file counts it; others: North through East)
    E        elevation
    Z        zenith distance, 90 deg - E
    H        hour angle (equatorial mounts; positive West)
    D        declination (equatorial mounts)
    N        observation number (1-based order in the run)

Whole plots: ``GSMAP`` (also ``GMAP``): the sky map with residual vectors
(:mod:`pointax.plots.skymap`); ``GHIST`` (also ``G HIST``, ``GDIST``): histograms of
both components and of the on-sky distance; ``GSCAT`` (also ``G SCAT``): dE against
dS; ``A9``: the nine-panel alt-az set (also ``CALL A9`` in a procedure), in reading order::

    G S A    G Z A    G V A        dS, dZ, distance against azimuth
    G S Z    G Z Z    G AM Z       dS, dZ, dA against zenith distance
    GSCAT    GSMAP    GHIST        dE vs dS, sky map, histogram of the distance

``E9`` (equatorial mounts, also ``CALL E9``), the same set in the mount's own axes::

    G X H    G D H    G V H        dX = dH cos dec, d dec, distance against hour angle
    G X D    G D D    G V D        the same against declination
    GSCAT    GSMAP    GHIST

Masked (weight 0) and outlier observations are drawn in their own artists (gid
``'masked'``, ``'outlier'``), as in :mod:`pointax.plots.residuals`.
"""

from __future__ import annotations

import numpy as np

from ._mpl import new_figure
from .data import ResidualData, residual_data
from .residuals import draw_histogram, draw_points, draw_scatter, histogram_figure, scatter_figure, title_of
from .skymap import draw_skymap, skymap_figure

__all__ = [
    "ORDINATES", "ABSCISSAE", "WHOLE_PLOTS", "A9_PANELS", "E9_PANELS", "parse_command", "tpoint_graph", "draw_graph",
    "nine_panel_figure", "valid_commands",
]  # fmt: skip

ORDINATES = ("AM", "S", "A", "E", "Z", "V", "R", "D", "X", "H")
"""Residual codes (longest first, as the parser tries them)."""

ABSCISSAE = ("A", "E", "Z", "H", "D", "N")
"""Position codes."""

WHOLE_PLOTS = {
    "GSMAP": "GSMAP", "GMAP": "GSMAP", "GHIST": "GHIST", "GDIST": "GHIST", "GSCAT": "GSCAT", "A9": "A9", "E9": "E9",
}  # fmt: skip
"""Names of whole plots -> the canonical name."""

A9_PANELS = ("G S A", "G Z A", "G V A", "G S Z", "G Z Z", "G AM Z", "GSCAT", "GSMAP", "GHIST")
"""The nine panels of A9, in reading order (rows of three)."""

E9_PANELS = ("G X H", "G D H", "G V H", "G X D", "G D D", "G V D", "GSCAT", "GSMAP", "GHIST")
"""The nine panels of pointax's E9, A9's counterpart for equatorial mounts: the
cross-declination and declination residuals and the distance against hour angle, then
against declination, then the scatter, the map and the histogram."""

NINE_PANELS = {"A9": A9_PANELS, "E9": E9_PANELS}

_EQUATORIAL_ONLY = {"H"}


def valid_commands() -> str:
    """The accepted command names, for error messages."""
    return (
        "G <residual> <position> with residual one of " + ", ".join(ORDINATES)
        + " and position one of " + ", ".join(ABSCISSAE)
        + " (e.g. 'G S A', 'GZZ', 'G AM Z'); " + ", ".join(sorted(WHOLE_PLOTS))
    )


def parse_command(command: str) -> tuple[str, ...]:
    """``('A9',)``, ``('GSMAP',)``, ``('GHIST',)``, ``('GSCAT',)`` or ``('G', residual,
    position)`` for a command name (case and spaces do not matter).

    Raises:
        ValueError: an unknown command, naming the valid ones.
    """
    compact = "".join(str(command).upper().split())
    if compact in WHOLE_PLOTS:
        return (WHOLE_PLOTS[compact],)
    if compact.startswith("G"):
        rest = compact[1:]
        for y in ORDINATES:  # longest first: GAMZ is G AM Z
            if rest.startswith(y) and rest[len(y):] in ABSCISSAE:
                return ("G", y, rest[len(y):])
    raise ValueError(f"unknown TPOINT graphics command {command!r}; valid: {valid_commands()}")


def _equatorial(data: ResidualData) -> bool:
    return data.mount == "EquatorialMount"


def _horizon_residuals(data: ResidualData) -> tuple[np.ndarray, np.ndarray]:
    """(dS, dE) in the horizon frame: the fit's own components for alt-az mounts (the
    file's azimuth convention), else the residual resolved along North-East azimuth."""
    if data.mount == "AltAzMount":
        return data.residuals[:, 0], data.residuals[:, 1]
    return data.sky[:, 0], data.sky[:, 1]


def _position_azel(data: ResidualData) -> tuple[np.ndarray, np.ndarray, str]:
    if data.mount == "AltAzMount" and data.observed_angles is not None:
        return data.observed_angles[:, 0], data.observed_angles[:, 1], data.convention or "N-E"
    return data.azel[:, 0], data.azel[:, 1], "N-E"


def ordinate(data: ResidualData, code: str) -> tuple[np.ndarray, str]:
    """The residual named by ``code`` (``(n,)``, in ``data.unit``) and its label."""
    ds, de = _horizon_residuals(data)
    _, el, _ = _position_azel(data)
    if code == "X" and not _equatorial(data):
        return data.residuals[:, 0], f"dX = {data.symbols[0]}"
    if code in _EQUATORIAL_ONLY or (code == "X" or code == "D") and _equatorial(data):
        if not _equatorial(data):
            raise ValueError(f"residual {code!r} is an equatorial mount's (this fit's mount is {data.mount}); "
                             "alt-az residuals: S, X, A, E, Z, V")
        dec = np.radians(data.observed_angles[:, 1])
        if code == "X":
            return data.residuals[:, 0], "dX = dH cos dec"
        if code == "H":
            return data.residuals[:, 0] / np.cos(dec), "dH"
        return data.residuals[:, 1], "d dec"
    if code == "S":
        return ds, "dS = dA cos E"
    if code in ("A", "AM"):
        return ds / np.cos(np.radians(el)), "dA"
    if code == "E":
        return de, "dE"
    if code == "Z":
        return -de, "dZ = -dE"
    return data.distance, "on-sky distance"


def abscissa(data: ResidualData, code: str) -> tuple[np.ndarray, str]:
    """The position named by ``code`` (``(n,)``, degrees or a number) and its label."""
    az, el, convention = _position_azel(data)
    if code == "A":
        return az, f"azimuth ({convention}), deg"
    if code == "E":
        return el, "elevation, deg"
    if code == "Z":
        return 90.0 - el, "zenith distance, deg"
    if code == "N":
        return np.arange(1, len(data) + 1, dtype=float), "observation number"
    if not _equatorial(data):
        raise ValueError(f"position {code!r} is an equatorial mount's (this fit's mount is {data.mount}); "
                         "alt-az positions: A, E, Z, N")
    if code == "H":
        return data.observed_angles[:, 0], "hour angle (+W), deg"
    return data.observed_angles[:, 1], "declination, deg"


def draw_graph(ax, data: ResidualData, parsed: tuple[str, ...], *, legend: bool = False):
    """Draw one parsed command (not A9 or E9) on ``ax``."""
    name = parsed[0]
    if name == "GSMAP":
        draw_skymap(ax, data, legend=legend)
        ax.set_title("GSMAP: residual vectors on the sky (N up, E right)", fontsize="medium")
    elif name == "GHIST":
        draw_histogram(ax, data, data.distance, "on-sky distance")
        ax.set_title("GHIST: distribution of on-sky distance", fontsize="medium")
    elif name == "GSCAT":
        draw_scatter(ax, data, legend=legend)
        ax.set_title("GSCAT: dE vs dS", fontsize="medium")
    else:
        _, y_code, x_code = parsed
        y, y_label = ordinate(data, y_code)
        x, x_label = abscissa(data, x_code)
        draw_points(ax, data, x, y, legend=legend, size=3.5)
        ax.set_xlabel(x_label)
        ax.set_ylabel(f"{y_label}, {data.unit}")
        ax.set_title(f"G {y_code} {x_code}: {y_label} vs {x_label.split(',')[0]}", fontsize="medium")


def tpoint_graph(command: str, result, observations, *, outliers=None):
    """The plot TPOINT's graphics command ``command`` names, as a matplotlib Figure.

    Args:
        command: 'G S A', 'GZA', 'G AM Z', 'GSMAP', 'GHIST', 'GSCAT', 'A9', ... (see
            the module docstring for every code; case and spaces do not matter).
        result: a single fit's :class:`pointax.FitResult`.
        observations: the fitted :class:`pointax.Observations` (weight 0 = masked) or
            a run with ``.observations``.
        outliers: more observations to flag (indices or a boolean mask).

    Raises:
        ValueError: an unknown command (the message lists the valid ones), or an
            equatorial code on another mount.
    """
    parsed = parse_command(command)
    if parsed == ("GSMAP",):
        return skymap_figure(result, observations, outliers=outliers)
    if parsed == ("GHIST",):
        return histogram_figure(result, observations, outliers=outliers)
    if parsed == ("GSCAT",):
        return scatter_figure(result, observations, outliers=outliers)
    data = residual_data(result, observations, outliers)
    if parsed[0] in NINE_PANELS:
        return nine_panel_figure(result, data, parsed[0])
    fig = new_figure(8.0, 5.0)
    draw_graph(fig.add_subplot(), data, parsed, legend=True)
    fig.suptitle(title_of(result))
    return fig


def nine_panel_figure(result, data: ResidualData, name: str = "A9"):
    """A nine-panel set, ``'A9'`` (:data:`A9_PANELS`) or ``'E9'`` (:data:`E9_PANELS`,
    equatorial mounts only), each panel titled by its command."""
    if name == "E9" and not _equatorial(data):
        raise ValueError(f"E9 is the equatorial set (this fit's mount is {data.mount}): draw A9")
    fig = new_figure(15.0, 14.0)
    axes = fig.subplots(3, 3)
    for k, (ax, panel) in enumerate(zip(axes.ravel(), NINE_PANELS[name])):
        draw_graph(ax, data, parse_command(panel), legend=(k == 0))
    fig.suptitle(title_of(result, name))
    return fig
