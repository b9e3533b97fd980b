"""A fit as one self-contained HTML page: fit table, statistics, warnings, plots and
the residual listing.

The page needs nothing else: no network access, no scripts, the style inline and
every figure embedded as a base64 PNG (``<img src="data:image/png;base64,...">``).
Figures need matplotlib (``pip install 'pointax[plot]'``).

    html = fit_report(result, observations, run=run, title="MMT 2021-08-21")
    write_report("report.html", html)
"""

from __future__ import annotations

import base64
import datetime
import html
import io
import math
import os

import numpy as np

__all__ = ["fit_report", "heliostat_report", "figure_png_base64", "write_report", "REPORT_FIGURES"]

REPORT_FIGURES = ("summary", "tpoint9", "histogram")
"""The figures a report shows by default (kinds of :func:`pointax.plots.fit_figure`)."""

_STYLE = """
body { font-family: sans-serif; margin: 1.5em auto; max-width: 1400px; color: #222; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; border-bottom: 1px solid #ccc; margin-top: 1.6em; }
table { border-collapse: collapse; font-size: 0.9em; }
th, td { padding: 2px 8px; text-align: right; border-bottom: 1px solid #eee; }
th { background: #f3f3f3; } td.name, th.name { text-align: left; }
tr.masked td { color: #888; } tr.outlier td { color: #b00; }
.warn { color: #a40; } figure { margin: 1em 0; } img { max-width: 100%; height: auto; }
figcaption { font-size: 0.9em; color: #555; } pre { background: #f8f8f8; padding: 0.6em; overflow-x: auto; }
"""


_CAPTIONS = {
    "summary": "Residuals against each axis reading, their scatter and histogram, and the sky map",
    "residuals": "Each residual component against each axis reading, and against each other",
    "sky": "Residual vectors on the sky (zenith at the centre, North up, East right)",
    "scatter": "Elevation residual against cross-elevation residual",
    "histogram": "Histograms of the residual components and of the on-sky distance",
    "tpoint9": "TPOINT's nine-panel alt-az set (A9); each panel is titled by its command",
}


def figure_png_base64(fig, dpi: int = 96) -> str:
    """``fig`` as a base64 PNG (the text after ``data:image/png;base64,``)."""
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=dpi)
    return base64.b64encode(buffer.getvalue()).decode("ascii")


def _img(fig, caption: str, dpi: int) -> str:
    data = figure_png_base64(fig, dpi)
    alt = html.escape(caption, quote=True)
    return f'<figure><img alt="{alt}" src="data:image/png;base64,{data}"><figcaption>{html.escape(caption)}</figcaption></figure>'


def _number(x: float, fmt: str) -> str:
    x = float(x)
    return format(x, fmt) if math.isfinite(x) else "&ndash;"


def _page(title: str, body: list[str]) -> str:
    stamp = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    from .. import __version__

    return (
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
        f"<title>{html.escape(title)}</title>\n<style>{_STYLE}</style>\n</head>\n<body>\n"
        f"<h1>{html.escape(title)}</h1>\n<p>pointax {html.escape(__version__)}, {stamp}</p>\n"
        + "\n".join(body)
        + "\n</body>\n</html>\n"
    )


def _fit_table(result) -> str:
    from ..core.units import UNITS

    rows = ["<table><tr><th>#</th><th class=\"name\">term</th><th>value</th><th>sigma</th><th class=\"name\">unit</th></tr>"]
    for k, row in enumerate(result.table(), 1):
        rows.append(
            f"<tr><td>{k}</td><td class=\"name\">{html.escape(row['name'])}</td><td>{_number(row['value'], '+.4f')}</td>"
            f"<td>{_number(row['sigma'], '.4f')}</td><td class=\"name\">{html.escape(row['unit'])}</td></tr>"
        )
    for p in result.model.parameters:
        if p.name in result.model.fixed:
            value = float(result.model.get(p.name)) / UNITS[p.unit]
            rows.append(
                f"<tr><td></td><td class=\"name\">{html.escape(p.name)}</td><td>{_number(value, '+.4f')}</td>"
                f"<td>fixed</td><td class=\"name\">{html.escape(p.unit)}</td></tr>"
            )
    rows.append("</table>")
    return "\n".join(rows)


def _statistics(result, data) -> str:
    from .data import UNIT_SCALE

    scale = UNIT_SCALE[data.unit]
    items = [
        ("observations used", str(int(np.asarray(result.n_obs)))),
        ("masked (weight 0)", str(int(data.masked.sum()))),
        ("outliers (robust fit)", str(int(data.outlier.sum()))),
        (f"Sky RMS ({data.unit})", _number(data.sky_rms, ".4f")),
        (f"Popn SD ({data.unit})", _number(float(np.asarray(result.popn_sd)) / scale, ".4f")),
        (
            f"LOO RMS ({data.unit}): leave-one-out, from the hat matrix of the linearised fit (no refits)",
            _number(float(np.asarray(getattr(result, "loo_rms", np.nan))) / scale, ".4f"),
        ),
        ("converged", "yes" if bool(result.converged) else "NO"),
        ("iterations", str(int(np.asarray(result.iterations)))),
        ("solver, loss", f"{html.escape(result.solver)}, {html.escape(result.loss)}"),
        ("model", html.escape(result.model.describe())),
    ]
    return "<table>" + "".join(f"<tr><th class=\"name\">{k}</th><td class=\"name\">{v}</td></tr>" for k, v in items) + "</table>"


def _warnings(result) -> str:
    warnings = result.warnings()
    if not warnings:
        return "<p>No warnings.</p>"
    return "<ul>" + "".join(f"<li class=\"warn\">{html.escape(w)}</li>" for w in warnings) + "</ul>"


_AZIMUTH_WORDS = {"N-E": "from North through East", "S-E": "from South through East", "S-W": "from South through West"}


def _listing(data, lines=None, raw=None) -> str:
    """The residual listing: per observation, its file line, the raw axis readings,
    the residual components and on-sky distance, and whether it was used.

    ``raw``: ``(n, 2)`` the raw (encoder) readings in degrees as the file gives them
    (default: the mount's nominal axis angles of the readings, azimuth wrapped to
    0-360, which the header then says)."""
    a1, a2 = data.axis_names
    r1, r2 = data.symbols
    angles = data.axis_angles if raw is None else np.asarray(raw, float)
    where = ""
    if data.mount == "AltAzMount":
        counted = _AZIMUTH_WORDS.get(data.convention, data.convention or "")
        where = f", raw encoder, counted {counted}" + (", wrapped to 0-360" if raw is None else ", as in the file")
    head = (
        "<table><tr><th>#</th>" + ("<th>line</th>" if lines is not None else "")
        + f"<th>{html.escape(a1)} (deg{html.escape(where)})</th><th>{html.escape(a2)} (deg{', raw encoder' if where else ''})</th>"
        f"<th>{html.escape(r1)} ({data.unit})</th><th>{html.escape(r2)} ({data.unit})</th>"
        f"<th>distance ({data.unit})</th><th class=\"name\">status</th></tr>"
    )
    rows = [head]
    for i in range(len(data)):
        status = "masked" if data.masked[i] else ("outlier" if data.outlier[i] else "used")
        line = f"<td>{int(lines[i])}</td>" if lines is not None else ""
        rows.append(
            f"<tr class=\"{status}\"><td>{i + 1}</td>{line}<td>{_number(angles[i, 0], '.4f')}</td>"
            f"<td>{_number(angles[i, 1], '.4f')}</td><td>{_number(data.residuals[i, 0], '+.3f')}</td>"
            f"<td>{_number(data.residuals[i, 1], '+.3f')}</td><td>{_number(data.distance[i], '.3f')}</td>"
            f"<td class=\"name\">{status}</td></tr>"
        )
    rows.append("</table>")
    return "\n".join(rows)


def fit_report(
    result,
    observations,
    *,
    run=None,
    title: str | None = None,
    figures=REPORT_FIGURES,
    commands=(),
    outliers=None,
    notes=(),
    dpi: int = 96,
) -> str:
    """One fit as a self-contained HTML page (a string).

    Args:
        result: a single fit's :class:`pointax.FitResult`.
        observations: the fitted :class:`pointax.Observations` (weight 0 = masked), or
            a run with ``.observations`` (its weights are then the ones fitted).
        run: the run as read (for the file's line numbers and caption), optional.
        title: the page title (default: the run's caption or 'pointax fit').
        figures: kinds of :func:`pointax.plots.fit_figure` to embed.
        commands: TPOINT graphics commands (:func:`pointax.plots.tpoint_graph`) to embed.
        outliers: more observations to flag (indices or a boolean mask).
        notes: lines of text shown under the title (e.g. the command that made it).
        dpi: resolution of the embedded PNGs.
    """
    from .. import plots
    from .data import residual_data

    data = residual_data(result, observations, outliers)
    caption = (getattr(run, "caption", "") or getattr(result, "caption", "") or "").strip()
    title = title or caption or "pointax fit"
    body = [f"<p>{html.escape(n)}</p>" for n in notes]
    body += ["<h2>Fit</h2>", _fit_table(result), "<h2>Statistics</h2>", _statistics(result, data)]
    body += ["<h2>Warnings</h2>", _warnings(result), "<h2>Plots</h2>"]
    for kind in figures:
        caption = _CAPTIONS.get(kind, kind)
        body.append(_img(plots.fit_figure(result, observations, kind, outliers=outliers), caption, dpi))
    for command in commands:
        body.append(_img(plots.tpoint_graph(command, result, observations, outliers=outliers), command, dpi))
    lines = getattr(run, "lines", None)
    if lines is not None and len(lines) != len(data):
        lines = None
    raw = getattr(run, "encoder", None)
    if raw is not None and data.mount == "AltAzMount" and np.shape(raw) == (len(data), 2):
        raw = np.degrees(np.asarray(raw, float))  # the file's own numbers, not wrapped
    else:
        raw = None
    body += ["<h2>Residuals (observed minus model; rows counted from 1)</h2>", _listing(data, lines, raw)]
    return _page(title, body)


def heliostat_report(calibration, *, title: str | None = None, notes=(), dpi: int = 96) -> str:
    """A heliostat calibration (:func:`pointax.calibrate_heliostat`) as a
    self-contained HTML page: its report, the per-sample error figure and a table
    of the errors before, after and leave-one-out (mrad)."""
    from . import heliostat_figure

    body = [f"<p>{html.escape(n)}</p>" for n in notes]
    body += ["<h2>Fit</h2>", _fit_table(calibration.result), "<h2>Report</h2>",
             f"<pre>{html.escape(calibration.report())}</pre>", "<h2>Warnings</h2>", _warnings(calibration.result)]
    body += ["<h2>Plots</h2>", _img(heliostat_figure(calibration), "per-sample errors", dpi)]
    rows = ["<table><tr><th>#</th><th class=\"name\">sample</th><th>before (mrad)</th><th>after (mrad)</th>"
            "<th>leave-one-out (mrad)</th><th class=\"name\">status</th></tr>"]
    flagged = np.asarray(calibration.outliers, bool)
    for i, sample in enumerate(calibration.sample_ids):
        status = "outlier" if flagged[i] else "used"
        rows.append(
            f"<tr class=\"{status}\"><td>{i + 1}</td><td class=\"name\">{html.escape(str(sample))}</td>"
            + "".join(f"<td>{_number(float(getattr(calibration, k)[i]) * 1e3, '.3f')}</td>" for k in ("before", "after", "loo"))
            + f"<td class=\"name\">{status}</td></tr>"
        )
    rows.append("</table>")
    body += ["<h2>Errors per sample</h2>", "\n".join(rows)]
    return _page(title or "heliostat calibration", body)


def write_report(path: str | os.PathLike, page: str) -> str:
    """Write ``page`` (UTF-8); returns ``'HTML report, N kB, K images: PATH'``."""
    name = os.fspath(path)
    with open(name, "w", encoding="utf-8") as f:
        f.write(page)
    return f"HTML report, {os.path.getsize(name) / 1024:.0f} kB, {page.count('<img ')} images: {name}"
