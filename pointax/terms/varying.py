"""Terms whose coefficients vary with an auxiliary reading: a linear temperature
coefficient for any term (:func:`thermal`) and a polynomial, piecewise-linear or cubic
B-spline in time for any term (:func:`in_time`).

Each wraps a term (``"TF"``, a term object, or a user's :class:`~pointax.Term`): every
parameter ``p`` of the wrapped term becomes a function of the reading, and the wrapper's
hooks are the wrapped term's hooks at those values, so the physics is the wrapped
term's own. The wrapper's parameters are fitted jointly with the other terms'.

Names (as reports and model files show them; :meth:`pointax.Model.set` and ``get`` take
them): the term ``TF`` wrapped by ``thermal`` is ``TF@temperature`` (``TF@<reading>``
for another reading), with parameters

* one-parameter wrapped term: ``TF@temperature.value`` (the value at the reference
  reading) and ``TF@temperature.slope`` (per unit of the reading: per deg C);
* several parameters ``a``, ``b``: ``X@temperature.a``, ``X@temperature.a_slope``, ...

``in_time(term, degree=d)`` is ``TF@time``, parameters ``value``, ``t1`` ... ``td``
(``p(t) = value + t1 x + t2 x^2 + ...``, ``x = time - reference`` in days; several
parameters: ``a``, ``a_t1``, ...). With ``knots`` (MJD) it is ``TF@time-linear`` or
``TF@time-spline``, parameters ``k0`` ... (one per knot for piecewise-linear, one per
B-spline for the cubic; several parameters: ``a_k0`` ...). Every coefficient is in the
wrapped parameter's own display unit (arcsec for a pointing coefficient: arcsec per deg
C, arcsec per day^k).

The wrapper reads its reading with :meth:`pointax.Term.reading`, so its values come
from :class:`pointax.Observations`' ``readings`` in fits and from ``readings=`` in
:meth:`pointax.Model.__call__` and :func:`pointax.command`.
"""

from __future__ import annotations

import math
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..core.readings import bind_readings
from ..core.term import Term, param, param_fields, param_unit

__all__ = ["thermal", "in_time", "VaryingTerm", "Thermal", "InTime", "bspline_basis", "hat_basis"]

_HOOKS = ("encoder_offset", "base_rotation", "axes_rotation", "boresight_rotation", "sky_offset", "sky_offset_at")


class VaryingTerm(Term):
    """Base of the wrappers: a wrapped term whose every parameter is
    ``sum_k c_k f_k(reading)`` (:meth:`basis`), the ``c_k`` the wrapper's parameters.

    Subclasses are made per wrapped term by :func:`thermal` and :func:`in_time` (one
    class per wrapped class, parameter names and kind: a model built twice the same way
    has one structure, and a fit compiles once)."""

    linear_sky_offset: ClassVar[bool] = False
    neutral_at_zero: ClassVar[bool | None] = False  # never carried, switched off, by a model that lacks it
    inner_fields: ClassVar[tuple[str, ...]] = ()
    n_coefficients: ClassVar[int] = 1
    reading_name: ClassVar[str] = "temperature"
    suffix: ClassVar[str] = "temperature"

    template: Term = eqx.field(static=True, kw_only=True)
    """The wrapped term with every parameter 0.0 (configuration: hashable)."""

    @property
    def name(self) -> str:
        return f"{self.template.name}@{self.suffix}"

    def basis(self, x):
        """``(K,)`` functions of the reading ``x`` (a scalar) weighting the coefficients."""
        raise NotImplementedError

    def coefficients(self, field: str) -> list:
        """The wrapper's ``K`` coefficients of the wrapped parameter ``field``."""
        names = _coefficient_names(self.inner_fields, type(self).coefficient_suffixes())
        return [getattr(self, n) for n in names[field]]

    @classmethod
    def coefficient_suffixes(cls) -> tuple[str, ...]:
        """The suffixes naming the ``K`` coefficients of each wrapped parameter."""
        raise NotImplementedError

    def wrapped(self) -> Term:
        """The wrapped term at the current reading's parameter values (its readings,
        if it reads any, bound as well)."""
        f = self.basis(self.reading(self.reading_name))
        values = []
        for field in self.inner_fields:
            c = self.coefficients(field)
            values.append(sum((c[k] * f[k] for k in range(1, len(c))), c[0] * f[0]))
        inner = eqx.tree_at(lambda t: [getattr(t, n) for n in self.inner_fields], self.template, values)
        if inner.readings:
            inner = bind_readings(inner, self._bound_readings)
        return inner

    def _hook(self, hook: str, *args):
        # A hook the wrapped term does not override is None without reading anything.
        if getattr(type(self.template), hook) is getattr(Term, hook):
            return None
        return getattr(self.wrapped(), hook)(*args)

    def encoder_offset(self, encoder):
        return self._hook("encoder_offset", encoder)

    def base_rotation(self, angles):
        return self._hook("base_rotation", angles)

    def axes_rotation(self, angles):
        return self._hook("axes_rotation", angles)

    def boresight_rotation(self, angles):
        return self._hook("boresight_rotation", angles)

    def sky_offset(self, angles):
        if getattr(type(self.template), "sky_offset") is Term.sky_offset and (
            getattr(type(self.template), "sky_offset_at") is Term.sky_offset_at
        ):
            return None
        return self.wrapped().sky_offset(angles)

    def sky_offset_at(self, point):
        if getattr(type(self.template), "sky_offset") is Term.sky_offset and (
            getattr(type(self.template), "sky_offset_at") is Term.sky_offset_at
        ):
            return None
        return self.wrapped().sky_offset_at(point)


class Thermal(VaryingTerm):
    """``p(T) = value + slope (T - reference)``: see :func:`thermal`."""

    reference: float = eqx.field(static=True, kw_only=True, default=0.0)

    @classmethod
    def coefficient_suffixes(cls):
        return _suffixes(Thermal, "thermal", 0, 2)

    def basis(self, x):
        return [jnp.ones_like(x), x - self.reference]


class InTime(VaryingTerm):
    """A parameter polynomial (or piecewise-linear, or cubic B-spline) in time: see
    :func:`in_time`."""

    reading_name: ClassVar[str] = "time"
    degree: ClassVar[int] = 1
    kind: ClassVar[str] = "polynomial"
    reference: float = eqx.field(static=True, kw_only=True, default=0.0)
    knots: tuple[float, ...] | None = eqx.field(static=True, kw_only=True, default=None)

    @classmethod
    def coefficient_suffixes(cls):
        return _suffixes(InTime, cls.kind, cls.degree, cls.n_coefficients)

    def basis(self, x):
        if self.kind == "polynomial":
            dx = x - self.reference
            return [jnp.ones_like(dx)] + [dx**k for k in range(1, self.degree + 1)]
        knots = np.asarray(self.knots, np.float64)
        b = hat_basis(x, knots) if self.kind == "linear" else bspline_basis(x, knots)
        return [b[k] for k in range(b.shape[0])]


def hat_basis(x, knots: np.ndarray):
    """``(K,)`` piecewise-linear ("hat") functions at ``x`` for the increasing ``knots``
    ``(K,)``: a weight per knot, summing to 1; constant beyond the end knots."""
    x = jnp.clip(x, knots[0], knots[-1])
    out = []
    for k in range(len(knots)):
        left = (x - knots[k - 1]) / (knots[k] - knots[k - 1]) if k > 0 else None
        right = (knots[k + 1] - x) / (knots[k + 1] - knots[k]) if k < len(knots) - 1 else None
        if left is None:
            w = jnp.where(x <= knots[k + 1], right, 0.0)
        elif right is None:
            w = jnp.where(x >= knots[k - 1], left, 0.0)
        else:
            w = jnp.where(x <= knots[k], left, right)
        out.append(jnp.clip(w, 0.0, 1.0))
    return jnp.stack(out)


def bspline_basis(x, knots: np.ndarray):
    """``(K + 2,)`` clamped cubic B-splines at ``x`` on the breakpoints ``knots`` ``(K,)``
    (Cox-de Boor recursion; end breakpoints repeated 4 times), summing to 1; ``x`` is
    clamped to ``[knots[0], knots[-1]]`` (the spline is constant beyond its ends, as a
    drift is not extrapolated)."""
    t = np.concatenate([[knots[0]] * 3, knots, [knots[-1]] * 3]).astype(np.float64)
    x = jnp.clip(x, knots[0], knots[-1])
    n_intervals = len(t) - 1
    # degree 0: the interval holding x (the last non-empty one for x at the end)
    last = max(i for i in range(n_intervals) if t[i] < t[i + 1])
    b = [
        jnp.where((x >= t[i]) & ((x < t[i + 1]) | ((i == last) & (x <= t[i + 1]))), 1.0, 0.0)
        if t[i] < t[i + 1]
        else jnp.zeros_like(x)
        for i in range(n_intervals)
    ]
    for d in range(1, 4):
        nxt = []
        for i in range(n_intervals - d):
            term = jnp.zeros_like(x)
            if t[i + d] > t[i]:
                term = term + (x - t[i]) / (t[i + d] - t[i]) * b[i]
            if t[i + d + 1] > t[i + 1]:
                term = term + (t[i + d + 1] - x) / (t[i + d + 1] - t[i + 1]) * b[i + 1]
            nxt.append(term)
        b = nxt
    return jnp.stack(b)


def _coefficient_names(fields: tuple[str, ...], suffixes: tuple[str, ...]) -> dict[str, list[str]]:
    """Per wrapped field, the wrapper's field names of its coefficients: a one-parameter
    term's are ``value``/``slope``/``t1``/``k0``...; several parameters' are the field's
    name joined to the suffix (``a``, ``a_slope``, ``a_k0``)."""
    if len(fields) == 1:
        return {fields[0]: [s or "value" for s in suffixes]}
    return {f: [f"{f}_{s}" if s else f for s in suffixes] for f in fields}


_CLASSES: dict = {}


def _wrapper_class(base: type, inner: Term, reading: str, suffix: str, extra: dict):
    """The wrapper class for ``inner``'s class (made once per wrapped class, reading,
    suffix and coefficient set: models built the same way share one structure)."""
    fields = tuple(f.name for f in param_fields(inner))
    if not fields:
        raise ValueError(f"term {inner.name} has no parameter to make vary with {reading!r}")
    key = (base, type(inner), fields, reading, suffix, tuple(sorted(extra.items())))
    if key in _CLASSES:
        return _CLASSES[key]
    attrs = dict(extra, inner_fields=fields, reading_name=reading, suffix=suffix)
    attrs["readings"] = tuple(sorted({reading, *inner.readings}))
    suffixes = _suffixes(base, attrs.get("kind", "thermal"), attrs.get("degree", 0), attrs.get("n_coefficients", 0))
    names = _coefficient_names(fields, suffixes)
    units = {f.name: param_unit(f) for f in param_fields(inner)}
    annotations = {}
    for field in fields:
        for n in names[field]:
            annotations[n] = float
            attrs[n] = param(0.0, unit=units[field])
    attrs.update(n_coefficients=len(suffixes), __annotations__=annotations, __module__=__name__)
    attrs["__doc__"] = f"{type(inner).__name__} ({', '.join(fields)}) varying with {reading!r} ({base.__name__})."
    cls = type(f"{type(inner).__name__}_{suffix.replace('-', '_')}", (base,), attrs)
    _CLASSES[key] = cls
    return cls


def _suffixes(base: type, kind: str, degree: int, n: int) -> tuple[str, ...]:
    """The coefficients' suffixes: ``("", "slope")`` (thermal), ``("", "t1", ...)``
    (polynomial in time), ``("k0", ...)`` (knots)."""
    if base is Thermal:
        return ("", "slope")
    if kind == "polynomial":
        return ("",) + tuple(f"t{k}" for k in range(1, degree + 1))
    return tuple(f"k{k}" for k in range(n))


def _as_term(term, mount: str | None) -> Term:
    if isinstance(term, Term):
        return term
    if isinstance(term, str):
        from .library import tpoint

        built = tpoint(term) if mount is None else tpoint(term, mount=mount)
        if len(built) != 1:
            raise ValueError(f"give one term to make vary, got {term!r} ({len(built)} terms)")
        return built[0]
    raise TypeError(f"expected a pointax.Term or a TPOINT term name, got {term!r}")


def _wrap(cls, inner: Term, static: dict):
    """An instance of the wrapper class ``cls`` around ``inner``: the first coefficient
    of each parameter at the wrapped term's value, the others 0."""
    obj = cls(template=_zeroed(inner), **static)
    names = _coefficient_names(cls.inner_fields, cls.coefficient_suffixes())
    first = [names[f][0] for f in cls.inner_fields]
    return eqx.tree_at(lambda t: [getattr(t, n) for n in first], obj, [getattr(inner, f) for f in cls.inner_fields])


def _zeroed(inner: Term) -> Term:
    """``inner`` with every parameter the Python float 0.0 (hashable: a static field)."""
    fields = [f.name for f in param_fields(inner)]
    return eqx.tree_at(lambda t: [getattr(t, f) for f in fields], inner, [0.0] * len(fields), is_leaf=lambda x: x is None)


def thermal(term, reading: str = "temperature", reference: float = 0.0, mount: str | None = None) -> Thermal:
    """``term`` with each parameter linear in an auxiliary reading:
    ``p = value + slope (reading - reference)``.

    Args:
        term: a term, or one TPOINT term name (``"TF"``; ``mount`` as for
            :func:`pointax.terms.tpoint`).
        reading: the reading it follows (default ``"temperature"``, deg C;
            :data:`pointax.core.readings.READINGS`).
        reference: the reading at which ``value`` applies (deg C for temperature).

    Returns:
        a term named ``<term>@<reading>`` (``TF@temperature``) with parameters
        ``value`` (the wrapped term's value at ``reference``, started at its current
        value) and ``slope`` (per unit of the reading, in the wrapped parameter's
        display unit: arcsec per deg C), named as the module docstring says.
    """
    inner = _as_term(term, mount)
    reference = float(reference)
    if not math.isfinite(reference):
        raise ValueError(f"reference must be finite, got {reference!r}")
    cls = _wrapper_class(Thermal, inner, reading, reading, {})
    return _wrap(cls, inner, {"reference": reference})


def in_time(term, degree: int = 1, reference: float | None = None, knots=None, spline: str = "cubic", mount: str | None = None) -> InTime:
    """``term`` with each parameter a smooth function of time (the ``time`` reading, MJD
    days).

    Args:
        term: a term, or one TPOINT term name.
        degree: without ``knots``: the polynomial's degree in ``x = time - reference``
            days (1: a linear drift).
        reference: MJD at which ``value`` applies (required without ``knots``).
        knots: increasing MJDs (at least 2): the parameter is a piecewise-linear
            function with a value at each knot (``spline="linear"``), or a clamped cubic
            B-spline on these breakpoints (``spline="cubic"``, the default; ``len(knots)
            + 2`` coefficients, at least 2 knots), constant beyond the end knots.

    Returns:
        a term named ``<term>@time`` (polynomial), ``<term>@time-linear`` or
        ``<term>@time-spline``; parameter names in the module docstring. The value
        coefficients start at the wrapped term's values, the others at 0.
    """
    inner = _as_term(term, mount)
    if knots is None:
        if reference is None:
            raise ValueError("in_time needs reference=<MJD> (the epoch at which the term's value applies)")
        degree = int(degree)
        if degree < 0:
            raise ValueError(f"degree must be >= 0, got {degree}")
        cls = _wrapper_class(InTime, inner, "time", "time", {"degree": degree, "kind": "polynomial"})
        return _wrap(cls, inner, {"reference": float(reference)})
    knots = tuple(float(k) for k in np.asarray(knots, np.float64).ravel())
    if len(knots) < 2 or not all(b > a for a, b in zip(knots, knots[1:])):
        raise ValueError(f"knots must be at least 2 increasing MJDs, got {knots}")
    if spline not in ("linear", "cubic"):
        raise ValueError(f"spline must be 'linear' or 'cubic', got {spline!r}")
    n = len(knots) if spline == "linear" else len(knots) + 2
    suffix = "time-linear" if spline == "linear" else "time-spline"
    cls = _wrapper_class(InTime, inner, "time", suffix, {"kind": spline, "n_coefficients": n})
    obj = cls(template=_zeroed(inner), knots=knots)
    # Every knot coefficient starts at the wrapped term's value (the functions sum to 1).
    names = _coefficient_names(cls.inner_fields, cls.coefficient_suffixes())
    for field in cls.inner_fields:
        value = getattr(inner, field)
        obj = eqx.tree_at(lambda t: [getattr(t, n) for n in names[field]], obj, [value] * n)
    return obj
