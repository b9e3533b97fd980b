"""pointax: differentiable telescope and sun-tracker pointing models in JAX.

Mount models are chains of rotations with pluggable error terms; fits use optimistix
with Jacobians from JAX and report TPOINT's statistics. Everything numerical is pure
JAX in float64 (see :mod:`pointax._x64` for how float64 is switched on).

    import pointax as px
    run = px.io.read_tpoint("examples/data/mmt_20210821.dat", azimuth="S-E")
    model = px.AltAz(px.terms.tpoint("IA IE NPAE CA AN AW TF TX"), azimuth=run.azimuth)
    print(px.fit(model, run).report())
"""

from . import distributed, io, network, rotations, sky, stars, terms, trig, units
from .batch import fit_batch, site_result, site_statuses, stack_observations
from .command import Command, command, command_reflector, reflect_normal
from .compare import Comparison, ModelBuild, build_model, compare
from .compilation_cache import enable_compilation_cache
from .fit import FitResult, fit, residuals
from .heliostat import HeliostatCalibration, calibrate_heliostat, heliostat_model
from .model import AltAz, Model, ParameterInfo, Turntable
from .mount_models import XY, XY_FAMILIES, Equatorial, xy_family
from .mounts import (
    AZIMUTH_CONVENTIONS,
    AltAzMount,
    EquatorialMount,
    HeliostatMount,
    Mount,
    SphericalMount,
    TurntableMount,
    XYMount,
)
from .network import fit_network
from .observations import Observations
from .shared import SharedFit, fit_shared
from .simulate import simulate
from .terms import Term, param
from .units import arcsec, deg, rad
from .validate import LeaveOneOut, leave_one_out

__version__ = "0.1.0"

__all__ = [
    "AltAz",
    "AltAzMount",
    "AZIMUTH_CONVENTIONS",
    "Command",
    "Comparison",
    "ModelBuild",
    "build_model",
    "compare",
    "Equatorial",
    "EquatorialMount",
    "FitResult",
    "HeliostatCalibration",
    "HeliostatMount",
    "LeaveOneOut",
    "Model",
    "Mount",
    "Observations",
    "ParameterInfo",
    "Term",
    "arcsec",
    "deg",
    "distributed",
    "enable_compilation_cache",
    "calibrate_heliostat",
    "command",
    "command_reflector",
    "fit",
    "fit_batch",
    "fit_network",
    "heliostat_model",
    "leave_one_out",
    "network",
    "io",
    "param",
    "rad",
    "reflect_normal",
    "residuals",
    "rotations",
    "SharedFit",
    "fit_shared",
    "simulate",
    "SphericalMount",
    "site_result",
    "site_statuses",
    "stack_observations",
    "sky",
    "stars",
    "terms",
    "trig",
    "Turntable",
    "TurntableMount",
    "units",
    "XY",
    "XY_FAMILIES",
    "XYMount",
    "xy_family",
]
