"""The predicted-accuracy sky map (:meth:`pointax.planning.PredictedAccuracy.skymap`)."""

from __future__ import annotations

import numpy as np

from ..core.units import ARCSEC

__all__ = ["accuracy_skymap"]


def accuracy_skymap(accuracy, *, resolution_deg=2.0, min_elevation_deg=20.0, max_elevation_deg=85.0, title=None, ax=None):
    """A polar map (zenith at centre, North up, East right: the projection of
    :mod:`pointax.plots.skymap`) of the predicted pointing error (arcsec), filled
    contours over ``min..max`` elevation, with the observations as dots. Returns the
    Figure."""
    from ..plots._mpl import new_figure
    from ..plots.skymap import draw_map_grid, map_positions
    from .candidates import directions_azel

    from ..core.rotations import azel_to_enu_numpy

    az = np.arange(0.0, 360.0 + 0.5 * resolution_deg, resolution_deg)
    el = np.arange(min_elevation_deg, max_elevation_deg + 1e-9, resolution_deg)
    a, e = np.meshgrid(az, el)
    sigma = accuracy.total(azel_to_enu_numpy(np.radians(a.ravel()), np.radians(e.ravel()))) / ARCSEC
    xy = map_positions(np.stack([a.ravel(), e.ravel()], axis=-1))
    if ax is None:
        fig = new_figure(7.0, 6.2)
        ax = fig.add_subplot()
    else:
        fig = ax.figure
    x, y = xy[:, 0].reshape(a.shape), xy[:, 1].reshape(a.shape)
    mesh = ax.pcolormesh(x, y, sigma.reshape(a.shape), shading="gouraud", cmap="viridis", gid="accuracy")
    fig.colorbar(mesh, ax=ax, shrink=0.8, label="predicted pointing error (RMS, arcsec)")
    draw_map_grid(ax)
    if accuracy.observations is not None and len(accuracy.observations):
        oaz, oel = directions_azel(accuracy.observations)
        pos = map_positions(np.degrees(np.stack([oaz, oel], axis=-1)))
        ax.plot(pos[:, 0], pos[:, 1], "o", color="white", markeredgecolor="black", markersize=4.5, linestyle="none",
                label=f"observations ({len(pos)})", gid="observations")  # fmt: skip
        ax.legend(loc="upper right", fontsize="small", bbox_to_anchor=(1.0, 1.02))
    if title is None:
        # The figures of accuracy.summary(): over the plan's sky (a sun plan: the sun's
        # path), the same as the plan's table, named as it names them.
        s = accuracy.summary(accuracy.sky)
        where = {None: "sky", "grid": "sky", "path": "path", "sun path": "sun's path"}.get(accuracy.sky_name, "given sky")
        title = f"predicted pointing error: RMS over the {where} {s['rms_arcsec']:.3f}\", max {s['max_arcsec']:.3f}\""
    ax.set_title(title, fontsize="medium")
    return fig
