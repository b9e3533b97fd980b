"""The conventions figure of docs/conventions.md, drawn at build time.

Left: the horizon seen from above (East-North-Up, North up, East right) with one
direction's azimuth counted the three ways pointax reads (``AZIMUTH_CONVENTIONS``:
N-E, S-E, S-W), each computed through the convention's frame change, not written
in. Right: the tangent plane at that direction: the two residual components (cross-
elevation along increasing azimuth, elevation), from ``pointax.core.rotations``.

    python docs/_scripts/conventions_figure.py OUT.png
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

AZ_NE, EL = 60.0, 35.0  # deg: the example direction (North through East)
COLOURS = {"N-E": "tab:blue", "S-E": "tab:orange", "S-W": "tab:green"}


def azimuths() -> dict[str, float]:
    """The example direction's azimuth in each convention, degrees in [0, 360)."""
    from pointax.core.mounts import AZIMUTH_CONVENTIONS

    a, e = np.radians(AZ_NE), np.radians(EL)
    enu = np.array([np.sin(a) * np.cos(e), np.cos(a) * np.cos(e), np.sin(e)])
    out = {}
    for name, frame in AZIMUTH_CONVENTIONS.items():
        x, y, _ = np.asarray(frame).T @ enu  # ENU -> the mount frame (azimuth from +y through +x)
        out[name] = float(np.degrees(np.arctan2(x, y)) % 360.0)
    return out


def _arc(ax, start_deg: float, sweep_deg: float, radius: float, colour: str, label: str) -> None:
    """An arc on the plan view from compass bearing ``start_deg``, ``sweep_deg``
    clockwise (positive: towards East from North)."""
    b = np.radians(start_deg + np.linspace(0.0, sweep_deg, 100))
    x, y = radius * np.sin(b), radius * np.cos(b)
    ax.plot(x, y, color=colour, lw=2)
    ax.annotate("", xy=(x[-1], y[-1]), xytext=(x[-3], y[-3]), arrowprops=dict(arrowstyle="->", color=colour, lw=2))
    mid = len(b) // 2
    ax.text(1.12 * x[mid], 1.12 * y[mid], label, color=colour, ha="center", va="center", fontsize=9)


def main(out: str | Path) -> Path:
    az = azimuths()
    fig, (plan, tangent) = plt.subplots(1, 2, figsize=(10.5, 5.0))

    # Plan view: bearing b (from North through East) is drawn at (sin b, cos b).
    t = np.linspace(0, 2 * np.pi, 200)
    plan.plot(np.cos(t), np.sin(t), color="0.6", lw=1)
    for word, (x, y) in {"N": (0, 1), "E": (1, 0), "S": (0, -1), "W": (-1, 0)}.items():
        plan.text(1.1 * x, 1.1 * y, word, ha="center", va="center", fontsize=12, weight="bold")
    r = np.cos(np.radians(EL))  # the direction's horizontal projection
    b = np.radians(AZ_NE)
    plan.plot([0, r * np.sin(b)], [0, r * np.cos(b)], color="k", lw=1.5)
    plan.plot(r * np.sin(b), r * np.cos(b), "k*", ms=14)
    # N-E: from North, clockwise on this view; S-E: from South, anticlockwise (through East);
    # S-W: from South, clockwise (through West). The sweeps are each convention's azimuth.
    _arc(plan, 0.0, az["N-E"], 0.35, COLOURS["N-E"], f"N-E: {az['N-E']:.0f}°")
    _arc(plan, 180.0, -az["S-E"], 0.55, COLOURS["S-E"], f"S-E: {az['S-E']:.0f}°")
    _arc(plan, 180.0, az["S-W"], 0.75, COLOURS["S-W"], f"S-W: {az['S-W']:.0f}°")
    plan.set_title(f"Azimuth of one direction (elevation {EL:.0f}°), three ways", fontsize=10)
    plan.set_aspect("equal")
    plan.set_xlim(-1.3, 1.3)
    plan.set_ylim(-1.3, 1.3)
    plan.axis("off")

    # Tangent plane: residual = observed - model, along (increasing azimuth, increasing elevation).
    tangent.axhline(0, color="0.7", lw=1)
    tangent.axvline(0, color="0.7", lw=1)
    tangent.annotate("", xy=(1, 0), xytext=(0, 0), arrowprops=dict(arrowstyle="->", lw=2))
    tangent.annotate("", xy=(0, 1), xytext=(0, 0), arrowprops=dict(arrowstyle="->", lw=2))
    tangent.text(1.02, -0.1, "cross-elevation\n(dA cos E, towards\nincreasing azimuth)", fontsize=9, va="top")
    tangent.text(0.05, 1.02, "elevation (dE, up)", fontsize=9)
    tangent.plot(0, 0, "k+", ms=12)
    tangent.text(-0.05, -0.08, "model", ha="right", va="top", fontsize=9)
    obs = np.array([0.55, 0.4])
    tangent.plot(*obs, "k*", ms=12)
    tangent.annotate("", xy=obs, xytext=(0, 0), arrowprops=dict(arrowstyle="->", color="tab:red", lw=1.5))
    tangent.text(obs[0] + 0.05, obs[1], "observed\nresidual = observed − model", fontsize=9, color="tab:red")
    tangent.set_xlim(-0.6, 1.7)
    tangent.set_ylim(-0.6, 1.3)
    tangent.set_aspect("equal")
    tangent.axis("off")
    tangent.set_title("Residuals in the tangent plane at the direction (radians inside, arcsec shown)", fontsize=10)

    fig.tight_layout()
    out = Path(out)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


if __name__ == "__main__":
    print(main(sys.argv[1] if len(sys.argv) > 1 else "conventions.png"))
