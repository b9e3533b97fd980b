"""A sky map with residual vectors (TPOINT's GSMAP).

The map is a polar (azimuthal equidistant) projection of the horizon frame: the
zenith at the centre, the horizon at radius 90 (zenith distance in degrees), North up
and East to the right, as on a map seen from above (a GNSS sky plot). Each observation
is a point at its observed azimuth and elevation; its residual (observed minus model)
is an arrow resolved on the sky in the horizon frame, whatever the mount, so an arrow
points from where the model points towards where the star was. A key arrow gives the
scale in the residual unit.

Artists: one ``Line2D`` of positions and one ``Quiver`` of arrows per kind of
observation (gid ``'used'``, ``'outlier'``, ``'masked'``; the quivers
``'<kind>-vectors'``). Positions are ``x = z sin A``, ``y = z cos A`` (z: zenith
distance, A: azimuth from North through East, degrees); arrow components are
``U = dS cos A - dE sin A``, ``V = -dS sin A - dE cos A`` in the residual unit
(dS: along increasing azimuth, dE: along increasing elevation).
"""

from __future__ import annotations

import numpy as np

from ._mpl import COLORS, LABELS, MARKERS, new_figure
from .data import ResidualData, residual_data

__all__ = ["map_positions", "map_vectors", "draw_skymap", "skymap_figure", "nice_length", "draw_map_grid"]


def map_positions(azel_deg: np.ndarray) -> np.ndarray:
    """``(n, 2)`` map coordinates (x East, y North; degrees of zenith distance) of
    ``(n, 2)`` azimuth (North through East) and elevation, degrees."""
    az = np.radians(azel_deg[:, 0])
    z = 90.0 - azel_deg[:, 1]
    return np.stack([z * np.sin(az), z * np.cos(az)], axis=1)


def map_vectors(azel_deg: np.ndarray, sky: np.ndarray) -> np.ndarray:
    """``(n, 2)`` map components of residuals ``sky`` = (along increasing azimuth,
    along increasing elevation) at ``azel_deg``: increasing azimuth turns clockwise
    (North to East), increasing elevation points to the centre."""
    az = np.radians(azel_deg[:, 0])
    s, e = sky[:, 0], sky[:, 1]
    return np.stack([s * np.cos(az) - e * np.sin(az), -s * np.sin(az) - e * np.cos(az)], axis=1)


def nice_length(values: np.ndarray) -> float:
    """A round length (1, 2 or 5 times a power of ten) near the 90th percentile of
    ``values`` (> 0), for a scale arrow."""
    finite = np.abs(values[np.isfinite(values)])
    ref = float(np.percentile(finite, 90)) if finite.size else 1.0
    if ref <= 0:
        ref = 1.0
    power = 10.0 ** np.floor(np.log10(ref))
    for step in (1.0, 2.0, 5.0, 10.0):
        if step * power >= ref * 0.999:
            return step * power
    return 10.0 * power  # pragma: no cover


def draw_map_grid(ax) -> None:
    """Draw the map's frame on ``ax``: elevation circles at 60, 30 and 0 deg (zenith
    distance 30, 60, 90), azimuth spokes every 45 deg, the N/E/S/W labels; equal aspect,
    no ticks (artists' gid ``'grid'``)."""
    t = np.linspace(0.0, 2 * np.pi, 361)
    for z in (30.0, 60.0, 90.0):
        ax.plot(z * np.sin(t), z * np.cos(t), color="0.75", linewidth=0.8 if z == 90 else 0.5, gid="grid")
        if z < 90:
            ax.text(z * np.sin(np.radians(20)), z * np.cos(np.radians(20)), f"{90 - z:.0f}\u00b0", color="0.5",
                    fontsize="x-small", ha="center", va="center")
    for a in range(0, 360, 45):
        r = np.radians(a)
        ax.plot([0, 90 * np.sin(r)], [0, 90 * np.cos(r)], color="0.85", linewidth=0.5, gid="grid")
    for label, a in (("N", 0), ("E", 90), ("S", 180), ("W", 270)):
        r = np.radians(a)
        ax.text(99 * np.sin(r), 99 * np.cos(r), label, ha="center", va="center", fontweight="bold")
    ax.set_xlim(-106, 106)
    ax.set_ylim(-106, 106)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    for spine in ax.spines.values():
        spine.set_visible(False)


def draw_skymap(ax, data: ResidualData, *, arrow_deg: float = 12.0, legend: bool = True) -> dict:
    """Draw the sky map on ``ax``. The key arrow (``arrow_deg`` degrees of map long)
    is a round residual length near the 90th percentile of the used observations'.
    Returns ``{'scale': units per map degree, 'key': key length in the unit}``."""
    draw_map_grid(ax)
    pos = map_positions(data.azel)
    vec = map_vectors(data.azel, data.sky)
    ref = np.hypot(vec[data.used, 0], vec[data.used, 1]) if data.used.any() else np.hypot(vec[:, 0], vec[:, 1])
    key = nice_length(ref)
    scale = key / arrow_deg  # residual units per degree of map
    quiver = None
    for group, mask in data.groups():
        if not mask.any():
            continue
        ax.plot(
            pos[mask, 0],
            pos[mask, 1],
            linestyle="none",
            marker=MARKERS[group],
            markersize=3.5,
            color=COLORS[group],
            markerfacecolor="none" if group == "masked" else COLORS[group],
            label=f"{LABELS[group]} ({int(mask.sum())})",
            gid=group,
        )
        q = ax.quiver(
            pos[mask, 0],
            pos[mask, 1],
            vec[mask, 0],
            vec[mask, 1],
            angles="xy",
            scale_units="xy",
            scale=scale,
            color=COLORS[group],
            width=0.004,
            gid=f"{group}-vectors",
        )
        quiver = quiver or q
    if quiver is not None:
        ax.quiverkey(quiver, 0.12, 0.02, key, f"{key:g} {data.unit}", labelpos="E", coordinates="axes")
    if legend:
        ax.legend(loc="upper right", fontsize="small", bbox_to_anchor=(1.0, 1.02))
    ax.set_title("on the sky: N up, E right, zenith at centre", fontsize="medium")
    return {"scale": scale, "key": key}


def skymap_figure(result, observations, *, outliers=None):
    """The sky map with residual vectors (GSMAP): a Figure."""
    from .residuals import title_of

    data = residual_data(result, observations, outliers)
    fig = new_figure(7.5, 7.5)
    draw_skymap(fig.add_subplot(), data)
    fig.suptitle(title_of(result))
    return fig
