"""A model-family comparison (:func:`pointax.compare`): RMS in and out of sample,
parameters and information criteria per family.

Left: grouped bars per family of the total RMS in sample and out of sample (the
level-mount paper's eqs 21-23, arcsec; gid ``'in-sample'`` and ``'out-of-sample'``,
bar ``k`` at x = k in the comparison's row order). Right: BIC relative to the best
family against the number of parameters (one point per family, ``Line2D`` gid
``'bic'``).
"""

from __future__ import annotations

import math

import numpy as np

from ._mpl import new_figure

__all__ = ["families_figure"]

ARCSEC = math.pi / (180.0 * 3600.0)


def families_figure(comparison, *, include_before: bool = False, title: str | None = None):
    """The comparison's families side by side: a Figure.

    Args:
        comparison: a :class:`pointax.analysis.Comparison`.
        include_before: also show the row without terms (before correction), whose
            RMS usually dwarfs the others.
    """
    rows = [r for r in comparison.rows if include_before or r.result is not None]
    if not rows:
        raise ValueError("the comparison has no fitted family to plot")
    labels = [r.label for r in rows]
    x = np.arange(len(rows), dtype=float)
    inside = np.array([r.in_sample.total / ARCSEC for r in rows])
    outside = np.array([r.out_of_sample.total / ARCSEC if r.out_of_sample is not None else np.nan for r in rows])
    fig = new_figure(max(9.0, 1.4 * len(rows) + 6.0), 4.8)
    grid = fig.add_gridspec(1, 2, width_ratios=(3, 2))
    ax = fig.add_subplot(grid[0, 0])
    width = 0.38
    for values, offset, gid, color, label in (
        (inside, -width / 2, "in-sample", "tab:blue", "in sample"),
        (outside, width / 2, "out-of-sample", "tab:orange", "out of sample"),
    ):
        if not np.isfinite(values).any():
            continue
        bars = ax.bar(x + offset, np.nan_to_num(values), width, color=color, label=label)
        for patch in bars.patches:
            patch.set_gid(gid)
        for xi, v in zip(x + offset, values):
            if np.isfinite(v):
                ax.text(xi, v, f"{v:.2f}", ha="center", va="bottom", fontsize="x-small")
    ax.set_xticks(x)
    ax.set_xticklabels(labels, rotation=20 if len(rows) > 4 else 0, ha="right" if len(rows) > 4 else "center")
    ax.set_ylabel("total RMS (eqs 21-23), arcsec")
    ax.set_title(comparison.description or "RMS per family", fontsize="medium")
    ax.legend(fontsize="small")

    ax2 = fig.add_subplot(grid[0, 1])
    bic = np.array([r.bic for r in rows], float)
    finite = np.isfinite(bic)
    rel = bic - (bic[finite].min() if finite.any() else 0.0)
    n_params = np.array([r.n_params for r in rows], float)
    ax2.plot(n_params, rel, linestyle="none", marker="o", color="tab:purple", gid="bic")
    for p, b, label in zip(n_params, rel, labels):
        if np.isfinite(b):
            ax2.annotate(label, (p, b), textcoords="offset points", xytext=(4, 4), fontsize="small")
    ax2.set_xlabel("fitted parameters")
    ax2.set_ylabel("BIC - best BIC")
    ax2.set_title("information criterion", fontsize="medium")
    fig.suptitle(title or f"model families: {comparison.n_fit} stars fitted, {comparison.n_validation} validated")
    return fig
