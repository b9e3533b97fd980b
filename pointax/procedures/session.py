"""The state of a TPOINT session: the run, the model's terms and values, masks, the
last fit, defined procedures and the current figure.

The model is kept as TPOINT keeps it: an ordered list of term names with a value each
(radians) and the set of fixed names. :meth:`Session.model` builds the
:class:`pointax.Model` of that state; a mask is a weight of 0
(:meth:`Session.weights`), so changing the terms, the fixed names or the masks never
changes the compiled structure of a fit (:func:`pointax.fitting.embed`).
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path
from collections.abc import Callable
from typing import Any, TextIO

import numpy as np

__all__ = ["Session", "MOUNTS", "read_run"]

MOUNTS = ("altaz", "equatorial")
"""Mounts ``pointax tpoint --mount`` names for runs whose files do not say (those of
:data:`pointax.io.tpoint.MOUNTS`)."""


def read_run(path: str | Path, mount: str = "altaz", azimuth: str = "N-E"):
    """Read a TPOINT input file; ``mount`` ('altaz' or 'equatorial') is the mount of a
    file whose option records name none (TPOINT's default is equatorial; some
    observatories' TPOINT is set to alt-az, and their files omit ``: ALTAZ``). A file
    that names its mount is read as it says.

    Raises:
        ValueError: an unknown mount.
        pointax.io.TpointFormatError: a malformed file (naming file, line, field).
        OSError: the file cannot be read.
    """
    from ..io.tpoint import MountNotGivenError, read_tpoint

    if mount not in MOUNTS:
        raise ValueError(f"unknown mount {mount!r}; expected one of {', '.join(MOUNTS)}")
    try:
        return read_tpoint(path, azimuth=azimuth)
    except MountNotGivenError:
        return read_tpoint(path, azimuth=azimuth, mount=mount)


@dataclasses.dataclass
class Session:
    """What a ``pointax tpoint`` session holds.

    Attributes:
        out: where reports go (standard output by default).
        mount: the mount of runs whose files name none, 'altaz' (default) or
            'equatorial'.
        azimuth: how the run files count azimuth ('N-E', 'S-E', 'S-W').
        form: TPOINT term form, 'rigorous' (default: the model applied as TPOINT
            applies it) or 'linear' (TPOINT's formulas as first-order offsets).
        residual_form: 'sky' (the model applied rigorously, as TPOINT's FIT) or
            'tpoint' (TPOINT's linearised residuals).
        run: the run read by INDAT (None before).
        terms: the terms in use, in order (upper-case TPOINT names).
        values: each term's value, radians (terms lost keep no value).
        fixed: names of fixed terms.
        parallel: names of the terms flagged ``&`` (added by FAUTO, or so flagged in the
            model file INMOD read); OUTMOD writes the flag back.
        masked: ``(n,)`` bool, masked observations of the run.
        result: the last FIT's :class:`pointax.FitResult` (None before one).
        stale: whether the model or the masks changed since that FIT.
        caption: the caption (CAPT; default the run's).
        refraction: refraction constants (A, B) of the model file INMOD read, written
            back by OUTMOD (None: 0, 0).
        procedures: defined procedures, by upper-case name: their lines.
        figure: the current figure: the last plot drawn, or the PLTZ page.
        show_caption: whether plots show the caption (CAPT ON / CAPT OFF).
        zone: the PLTZ panel the next plot goes in (None: a whole figure).
        page: ``(figure, axes)`` of the open PLTZ page (None when none is open).
        device: the file the last GC wrote (GC alone keeps it).
        prepare: called once, before the first command that computes (``pointax
            tpoint`` turns JAX's compilation cache on there, so that a script that
            only asks for HELP or fails at its first word never imports JAX).
    """

    out: TextIO = dataclasses.field(default_factory=lambda: sys.stdout)
    mount: str = "altaz"
    azimuth: str = "N-E"
    form: str = "rigorous"
    residual_form: str = "sky"
    run: Any = None
    terms: list[str] = dataclasses.field(default_factory=list)
    values: dict[str, float] = dataclasses.field(default_factory=dict)
    fixed: set[str] = dataclasses.field(default_factory=set)
    parallel: set[str] = dataclasses.field(default_factory=set)
    masked: np.ndarray | None = None
    result: Any = None
    stale: bool = True
    caption: str | None = None
    refraction: tuple[float, float] | None = None
    procedures: dict[str, list] = dataclasses.field(default_factory=dict)
    figure: Any = None
    show_caption: bool = True
    zone: str | None = None
    page: Any = None
    device: str | None = None
    prepare: Callable[[], Any] | None = None

    def say(self, text: str = "") -> None:
        """Print ``text`` to :attr:`out`."""
        print(text, file=self.out)

    def ready(self) -> None:
        """Run :attr:`prepare` (once) before a command that computes."""
        prepare, self.prepare = self.prepare, None
        if prepare is not None:
            prepare()

    def require_run(self):
        """The run; ValueError when INDAT has not read one."""
        if self.run is None:
            raise ValueError("no data: read a run with INDAT FILE first")
        return self.run

    def model(self):
        """The model (:meth:`pointax.io.TpointRun.model`: alt-az or equatorial) of the
        current terms, values and fixed names (terms not yet fitted at 0)."""
        from ..terms import tpoint

        run = self.require_run()
        values = {n: self.values.get(n, 0.0) for n in self.terms}
        terms = tpoint(self.terms, form=self.form, values=values, **self.term_options())
        return run.model(terms, fixed=sorted(self.fixed), residual_form=self.residual_form)

    def term_options(self) -> dict[str, Any]:
        """How term names resolve for the run at hand: ``{}`` for alt-az (and before
        INDAT), the mount and latitude for an equatorial run (:func:`pointax.terms.tpoint`)."""
        return {} if self.run is None else self.run.term_options()

    def weights(self) -> np.ndarray:
        """``(n,)`` the run's weights with masked observations at 0."""
        run = self.require_run()
        base = np.asarray(run.observations.weight, np.float64)
        return np.where(self.masked, 0.0, base)

    def observations(self):
        """The run's :class:`pointax.Observations` with masked ones at weight 0 (what
        plots draw as masked)."""

        obs = self.require_run().observations
        return obs.with_weight(self.weights())

    def current_caption(self) -> str:
        """The caption CAPT set, else the run's, else ``'pointax tpoint'``."""
        if self.caption:
            return self.caption
        return self.run.caption if self.run is not None else "pointax tpoint"
