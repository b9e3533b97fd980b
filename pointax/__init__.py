"""pointax: differentiable telescope and sun-tracker pointing models in JAX.

Mount models are chains of rotations with pluggable error terms; fits use optimistix
with Jacobians from JAX and report TPOINT's statistics. Everything numerical is pure
JAX in float64 (see :mod:`pointax._x64` for how float64 is switched on).

    import pointax as px
    run = px.io.read_tpoint("examples/data/mmt_20210821.dat", azimuth="S-E")
    model = px.AltAz(px.terms.tpoint("IA IE NPAE CA AN AW TF TX"), azimuth=run.azimuth)
    print(px.fit(model, run).report())

The names below load from their modules on first use (PEP 562, :mod:`pointax._lazy`):
``import pointax`` imports no numerical library, and astropy (:mod:`pointax.sky`,
:mod:`pointax.stars`), torch (:mod:`pointax.sunsensor`), dask
(:mod:`pointax.distributed`) and the solvers load when something needs them.
"""

from ._lazy import lazy_namespace

__version__ = "0.1.0"

# Public name -> the module that defines it.
_EXPORTS = {
    "fit_batch": "batch",
    "site_result": "batch",
    "site_statuses": "batch",
    "stack_observations": "batch",
    "Command": "command",
    "command": "command",
    "command_reflector": "command",
    "reflect_normal": "command",
    "Comparison": "analysis",
    "ModelBuild": "analysis",
    "build_model": "analysis",
    "Fauto": "analysis",
    "fauto": "analysis",
    "compare": "analysis",
    "enable_compilation_cache": "compilation_cache",
    "FitOptions": "fitting",
    "FitResult": "fitting",
    "fit": "fitting",
    "residuals": "fitting",
    "HeliostatCalibration": "heliostat",
    "calibrate_heliostat": "heliostat",
    "heliostat_model": "heliostat",
    "AltAz": "mount_models",
    "Model": "model",
    "ParameterInfo": "model",
    "Turntable": "mount_models",
    "XY": "mount_models",
    "XY_FAMILIES": "mount_models",
    "Equatorial": "mount_models",
    "xy_family": "mount_models",
    "AZIMUTH_CONVENTIONS": "mounts",
    "AltAzMount": "mounts",
    "EquatorialMount": "mounts",
    "HeliostatMount": "mounts",
    "Mount": "mounts",
    "SphericalMount": "mounts",
    "TurntableMount": "mounts",
    "XYMount": "mounts",
    "fit_network": "network",
    "Observations": "observations",
    "SharedFit": "shared",
    "fit_shared": "shared",
    "simulate": "simulate",
    "Candidates": "planning",
    "Plan": "planning",
    "PredictedAccuracy": "planning",
    "plan_run": "planning",
    "predicted_accuracy": "planning",
    "Term": "terms",
    "param": "terms",
    "arcsec": "units",
    "deg": "units",
    "rad": "units",
    "LeaveOneOut": "validate",
    "leave_one_out": "validate",
}

# Submodules exported as themselves.
_SUBMODULES = ("analysis", "distributed", "fitting", "io", "network", "planning", "rotations", "sky", "stars", "terms", "trig", "units")

__getattr__, __dir__ = lazy_namespace(__name__, _EXPORTS, _SUBMODULES)

__all__ = [
    "AltAz",
    "AltAzMount",
    "AZIMUTH_CONVENTIONS",
    "Command",
    "Comparison",
    "ModelBuild",
    "build_model",
    "Fauto",
    "fauto",
    "compare",
    "Equatorial",
    "EquatorialMount",
    "FitOptions",
    "FitResult",
    "HeliostatCalibration",
    "HeliostatMount",
    "LeaveOneOut",
    "Model",
    "Mount",
    "Observations",
    "ParameterInfo",
    "Plan",
    "PredictedAccuracy",
    "Candidates",
    "Term",
    "arcsec",
    "deg",
    "analysis",
    "distributed",
    "enable_compilation_cache",
    "fitting",
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
    "plan_run",
    "planning",
    "predicted_accuracy",
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
