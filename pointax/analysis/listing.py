"""The residual listing of a fit: one entry per observation, and TPOINT's SLIST table.

For every observation of a run (used, masked or flagged as an outlier) it gives the
file line, the observed and raw encoder angles as the file gives them (degrees, the
file's azimuth convention; hour angle and declination for an equatorial run) and the
residuals of the fitted model: cross-elevation ``dX = dA cos E`` (cross-declination
``dH cos dec``), elevation ``dE`` (declination) and the on-sky distance
``dS = sqrt(dX^2 + dE^2)``,
observed minus model, arcsec, in the fit's residual form. They are those of
:func:`pointax.fitting.masking.observation_residuals`, as the plots' and the report's:
masked observations' are evaluated with the same fitted model, so a listing shows how
far a masked star lies from the fit.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..core.units import ARCSEC, DEG
from ..fitting.masking import observation_residuals, on_sky

__all__ = ["observation_entries", "format_listing", "LISTING_KEYS", "EQUATORIAL_KEYS"]

LISTING_KEYS = (
    "row",
    "line",
    "observed_az_deg",
    "observed_el_deg",
    "raw_az_deg",
    "raw_el_deg",
    "dx_arcsec",
    "de_arcsec",
    "ds_arcsec",
    "used",
    "masked",
    "outlier",
)
"""The keys of each entry of :func:`observation_entries` (``pointax fit --json``'s
``observations``) for alt-az and other runs; an equatorial run's entries name hour
angle and declination instead (:data:`EQUATORIAL_KEYS`)."""

EQUATORIAL_KEYS = tuple(
    k.replace("_az_", "_ha_").replace("_el_", "_dec_") for k in LISTING_KEYS
)
"""The keys of an equatorial run's entries: ``observed_ha_deg``, ``observed_dec_deg``,
``raw_ha_deg``, ``raw_dec_deg`` (hour angle positive West, degrees; the telescope's
declination beyond +-90 on the other side of the pier), ``dx_arcsec`` = dH cos dec,
``de_arcsec`` = d dec, and the rest as :data:`LISTING_KEYS`."""


def _equatorial(run) -> bool:
    return getattr(run, "mount", None) == "equatorial"


def _columns(run, result, masked, residuals=None) -> dict[str, np.ndarray]:
    n = len(run)
    masked = np.zeros(n, bool) if masked is None else masked
    rows = observation_residuals(result, run.observations, masked=masked, residuals=residuals)
    r = rows.residuals / ARCSEC
    lines = getattr(run, "lines", None)
    return {
        "row": np.arange(1, n + 1),
        "line": np.asarray(lines) if lines is not None else np.full(n, -1),
        # Observed positions: a TPOINT or gpoint run's stars, a sun run's sun positions.
        "observed": np.asarray(run.observed if hasattr(run, "observed") else run.sun, np.float64) / DEG,
        "raw": np.asarray(run.encoder, np.float64) / DEG,
        "dx": r[:, 0],
        "de": r[:, 1],
        "ds": on_sky(r),
        "used": rows.used,
        "masked": rows.masked,
        "outlier": rows.outlier,
    }


def observation_entries(run, result, masked=None, residuals=None) -> list[dict[str, Any]]:
    """One JSON-ready dict per observation of ``run``, in file order.

    Args:
        run: a run read by :mod:`pointax.io` with ``observed`` (or, for sun runs,
            ``sun``), ``encoder`` (``(n, 2)``
            radians, file convention), ``lines`` (``(n,)`` file line numbers) and
            ``observations``.
        result: the :class:`pointax.FitResult` of a fit to ``run``.
        masked: optional ``(n,)`` bool, the observations the fit was told to leave out.
        residuals: optional ``(n, 2)`` residuals (radians) of ``result.model`` at every
            observation, when the caller has them (default:
            :func:`pointax.fitting.masking.observation_residuals`).

    Returns:
        Dicts with :data:`LISTING_KEYS`: ``row`` (1-based, TPOINT's numbering),
        ``line`` (file line), observed and raw azimuth and elevation (degrees, as in the
        file), residuals ``dx_arcsec`` (dA cos E), ``de_arcsec``, ``ds_arcsec``
        (on-sky distance), ``used`` (in the final fit), ``masked``, ``outlier``
        (flagged by a robust fit).
    """
    c = _columns(run, result, masked, residuals)
    keys = EQUATORIAL_KEYS if _equatorial(run) else LISTING_KEYS
    # Column by column to Python numbers (``tolist``), then one dict per row: a network
    # report builds these for thousands of sites, and converting element by element cost
    # several times as much.
    whole = lambda x: np.asarray(x, np.int64).tolist()  # noqa: E731
    real = lambda x: np.asarray(x, np.float64).tolist()  # noqa: E731
    flag = lambda x: np.asarray(x, bool).tolist()  # noqa: E731
    columns = (
        whole(c["row"]), whole(c["line"]), real(c["observed"][:, 0]), real(c["observed"][:, 1]), real(c["raw"][:, 0]),
        real(c["raw"][:, 1]), real(c["dx"]), real(c["de"]), real(c["ds"]), flag(c["used"]), flag(c["masked"]),
        flag(c["outlier"]),
    )  # fmt: skip
    return [dict(zip(keys, row)) for row in zip(*(column[: len(run)] for column in columns))]


def format_listing(run, result, masked=None) -> str:
    """A residual table in the manner of TPOINT's SLIST: per observation its number,
    file line, observed and raw azimuth and elevation (degrees, as in the file) and
    the residuals dX = dA cos E, dE and dS (on-sky), arcsec; a flag ``M`` for masked
    and ``O`` for a robust fit's outlier. Arguments as :func:`observation_entries`."""
    c = _columns(run, result, masked)
    azimuth = getattr(run, "azimuth", None)
    if _equatorial(run):
        title = "Residuals, observed minus model (arcsec); hour angle (West +) and declination in degrees"
        header = "     #  line     HA obs   Dec obs     HA raw   Dec raw        dX        dD        dS"
    else:
        title = "Residuals, observed minus model (arcsec); angles in degrees as in the file" + (
            f" (azimuth {azimuth})" if azimuth else ""
        )
        header = "     #  line     Az obs    El obs     Az raw    El raw        dX        dE        dS"
    lines = [title, "", header]
    for i in range(len(run)):
        flag = "M" if c["masked"][i] else ("O" if c["outlier"][i] else "")
        text = (
            f"  {c['row'][i]:4d} {c['line'][i]:5d} {c['observed'][i, 0]:10.4f} {c['observed'][i, 1]:9.4f} "
            f"{c['raw'][i, 0]:10.4f} {c['raw'][i, 1]:9.4f} {c['dx'][i]:+9.2f} {c['de'][i]:+9.2f} {c['ds'][i]:9.2f}  {flag}"
        )
        lines.append(text.rstrip())
    used = c["used"]
    lines.append("")
    lines.append(
        f"{int(used.sum())} of {len(run)} observations used; {int(c['masked'].sum())} masked (M)"
        + (f", {int(c['outlier'].sum())} outlier(s) (O)" if c["outlier"].any() else "")
    )
    if used.any():
        lines.append(f"Sky RMS of the used observations = {float(result.sky_rms) / ARCSEC:.4f}")
    return "\n".join(lines)
