"""pointax: differentiable telescope and sun-tracker pointing models in JAX.

Mount models are chains of rotations with pluggable error terms; fits use optimistix
with Jacobians from JAX and report TPOINT's statistics. Everything numerical is pure
JAX in float64 (see :mod:`pointax._x64` for how float64 is switched on).

    import pointax as px
    run = px.io.read_tpoint("examples/data/mmt_20210821.dat", azimuth="S-E")
    model = px.AltAz(px.terms.tpoint("IA IE NPAE CA AN AW TF TX"), azimuth=run.azimuth)
    print(px.fit(model, run).report())
"""

from . import io, rotations, terms, units
from .fit import FitResult, fit, residuals
from .model import AltAz, Model, ParameterInfo, Turntable
from .mounts import AZIMUTH_CONVENTIONS, AltAzMount, Mount, TurntableMount
from .observations import Observations
from .simulate import simulate
from .terms import Term, param
from .units import arcsec, deg, rad

__version__ = "0.1.0"

__all__ = [
    "AltAz",
    "AltAzMount",
    "AZIMUTH_CONVENTIONS",
    "FitResult",
    "Model",
    "Mount",
    "Observations",
    "ParameterInfo",
    "Term",
    "arcsec",
    "deg",
    "fit",
    "io",
    "param",
    "rad",
    "residuals",
    "rotations",
    "simulate",
    "terms",
    "Turntable",
    "TurntableMount",
    "units",
]
