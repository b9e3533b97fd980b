"""TPOINT-style FAUTO (:func:`fauto`): start from the mount's basic physical terms, try
its further physical terms, then harmonics up to a chosen order, keep a term while it is
significant, drop terms that lose significance, never add a term that mimics one
already in the model, and report the steps, the weak outlier candidates and the pairs
of terms the data cannot reliably tell apart.

The rule (pointax's; TPOINT's manual and help files available to us describe FAUTO's
purpose, not its numerical rule, so the thresholds here are pointax's choice):

* **add**: among the candidates open at this stage, those whose ``|value / sigma|`` in
  the enlarged fit is at least ``significance`` (default 2), which lower TPOINT's
  Popn SD, and whose parameters' correlation with every parameter already fitted is
  within ``collinearity`` (default ``|r| <= 0.99``, from the enlarged fit's covariance
  ``(J^T J)^-1``) are eligible; the one with the lowest Popn SD is added (ties: the
  first in candidate order), and the model refitted;
* **drop**: after each addition, while a term FAUTO added has ``|value / sigma| <
  significance``, the least significant one is dropped (and not tried again); and,
  from the start fit on, while the refit without the least significant start term has
  the lower Popn SD, that term is dropped (``start_rule='popn'``; for a linear problem
  that is ``|value / sigma| < sqrt(N / (N - M))``): TPOINT's FAUTO models hold such
  basic terms at 0 (IE, CA, NPAE in the Rubin AuxTel models of
  ``benchmarks/fauto_notes.md``), and the 2 sigma bar of the added terms dropped
  correlated planted terms on a simulated run;
* **stages**: the further physical terms first; then the harmonics of every order up
  to ``max_order`` (default 8: TPOINT's FAUTO models hold harmonics to order 8, none
  higher) together (lower orders first in the candidate order, which breaks
  ties); a stage ends when no candidate is eligible. (Opening the orders one at a time
  lets a low-order harmonic take the place of a higher-order one the data hold: on a
  simulated run with HECE3, HECE2 came in at order 2 and HECE3 was then left out.)
  With ``max_product_order``, a last stage adds the two-coordinate products
  (``HSCA5CE8``; :func:`product_candidates`), the single harmonics still open;
* **exchange** (``exchanges=True``, default): when no candidate is eligible, each
  added term is left out in turn and the open candidates screened on the model
  without it (linearised at the model's fit: no refit per term); the swap with the
  lowest Popn SD is refitted and made if its Popn SD is below the model's
  (the term left out is not tried again; never for a candidate it cannot be told
  apart from, ``|partial r| > collinearity``, such as ``HSSA2CE`` for ``HASA2``), terms
  that lost significance dropped, and additions tried again; until no swap lowers
  Popn SD. A greedy search adds one term at a time and can keep an early term that a
  later one makes second best (measurements: ``benchmarks/fauto_notes.md``).

The fits are :class:`pointax.analysis.building_fits.Builder`'s (converged Gauss-Newton
fits on masks of terms: trying a term compiles nothing); candidates are screened by one
linearised step from the current fit, the one-parameter candidates all together in
NumPy (:meth:`_Search.screen_all`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Sequence
from typing import Any

import jax
import numpy as np

from ..core.precision import float64
from ..core.model import Model
from ..core.mounts import AltAzMount, EquatorialMount, XYMount
from ..terms import xy as xy_terms
from ..core.units import ARCSEC, UNITS
from .building_fits import Builder, FitState, _steps_program
from .families import family_model
from ..fitting.residuals import as_observations
from .folds import evaluation_scheme
from ..fitting.result import finite_or_none
from .per_axis import resolve_per_axis, second_axis_cosines

__all__ = ["FAUTO_PHYSICAL", "FautoStep", "Fauto", "fauto", "harmonic_candidates", "product_candidates"]

FAUTO_PHYSICAL: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "altaz": (("IA", "IE", "CA", "NPAE", "AN", "AW", "TF", "TX"), ("ACEC", "ACES", "ECEC", "ECES")),
    "equatorial": (("IH", "ID", "CH", "NP", "MA", "ME", "TF"), ("FO", "DAF", "TX", "HCES", "HCEC", "DCES", "DCEC")),
    "xy": (("basic",), ()),
}
"""Mount kind -> (basic physical terms, further physical terms) FAUTO starts from and
tries first. X-Y: the level-mount paper's basic family (:mod:`pointax.terms.xy`)."""


def _mount_kind(mount) -> str:
    if isinstance(mount, XYMount):
        return "xy"
    if isinstance(mount, EquatorialMount):
        return "equatorial"
    if isinstance(mount, AltAzMount):
        return "altaz"
    raise ValueError(f"FAUTO knows alt-az, equatorial and X-Y mounts, not a {type(mount).__name__}")


def _xy_degree(name: str) -> int:
    """Degree of an X-Y spherical-harmonic term (SHL_1: 0, SHL_sinB^2: 2, SHL_cosL_sinB_cosB: 2)."""
    body = name.split("_", 1)[1]
    if body == "1":
        return 0
    degree = 0
    for factor in body.split("_"):
        base, _, power = factor.partition("^")
        degree += int(power) if power else 1
    # cosL cosB and sinL cosB are degree 1 in the direction cosines: L factors do not count.
    return degree - sum(1 for f in body.split("_") if f.endswith("L"))


def harmonic_candidates(kind: str, order: int) -> tuple[str, ...]:
    """Harmonic term names of exactly ``order`` for a mount kind: alt-az TPOINT ``H{A,E,S}
    {S,C}{A,E}k`` (k = order), equatorial ``H{H,D,X}{S,C}{H,D}k``, X-Y the level-mount
    paper's spherical harmonics of that degree (order 1 also takes degree 0)."""
    if kind == "altaz":
        return tuple(f"H{w}{f}{a}{order}" for w in "AES" for f in "SC" for a in "AE")
    if kind == "equatorial":
        return tuple(f"H{w}{f}{a}{order}" for w in "HDX" for f in "SC" for a in "HD")
    if kind == "xy":
        return tuple(n for n in xy_terms.SphericalHarmonic.TABLE if max(_xy_degree(n), 1) == order)
    raise ValueError(f"unknown mount kind {kind!r}")


def _multiplier(k: int) -> str:
    return "" if k == 1 else str(k)


def product_candidates(kind: str, max_order: int) -> tuple[str, ...]:
    """Two-coordinate product harmonics with both orders in ``1..max_order``, in TPOINT's
    generic grammar (multiplier 1 left out, as TPOINT writes them): alt-az
    ``H{A,E,S}{S,C}A{k}{S,C}E{j}`` (``HESACE``, ``HSCA5CE8``), equatorial
    ``H{H,D,X}{S,C}H{k}{S,C}D{j}``; ordered by ``max(k, j)``, then ``k + j``. X-Y mounts
    have none (their harmonics, :mod:`pointax.terms.xy`, are already functions of both
    axes). ``12 max_order^2`` names."""
    if kind == "xy":
        return ()
    if kind not in ("altaz", "equatorial"):
        raise ValueError(f"unknown mount kind {kind!r}")
    results, (u, v) = ("AES", "AE") if kind == "altaz" else ("HDX", "HD")
    pairs = sorted(((k, j) for k in range(1, max_order + 1) for j in range(1, max_order + 1)),
                   key=lambda kj: (max(kj), sum(kj), kj))
    return tuple(f"H{w}{f}{u}{_multiplier(k)}{g}{v}{_multiplier(j)}"
                 for k, j in pairs for w in results for f in "SC" for g in "SC")


@dataclasses.dataclass(frozen=True)
class FautoStep:
    """One step of :func:`fauto`.

    Attributes:
        stage: 'start', 'physical', 'harmonic', 'product' or 'exchange'.
        action: 'start', 'add' or 'drop'.
        term: the term added or dropped (for 'start' the start model's terms).
        n_terms: fitted parameters after the step (M).
        sky_rms, popn_sd: TPOINT's Sky RMS and Popn SD after the step, radians.
        significance: the term's ``|value / sigma|`` (added: in the model it joined;
            dropped: in the model it left).
    """

    stage: str
    action: str
    term: str
    n_terms: int
    sky_rms: float
    popn_sd: float
    significance: float

    def to_dict(self) -> dict[str, Any]:
        return {
            "stage": self.stage,
            "action": self.action,
            "term": self.term,
            "n_terms": self.n_terms,
            "sky_rms_arcsec": finite_or_none(self.sky_rms / ARCSEC),
            "popn_sd_arcsec": finite_or_none(self.popn_sd / ARCSEC),
            "significance": finite_or_none(self.significance),
        }


@dataclasses.dataclass(frozen=True)
class Fauto:
    """The outcome of :func:`fauto`.

    Attributes:
        model: the final model, fitted (converged) on the observations.
        steps: the :class:`FautoStep` s, 'start' first.
        added: names of the terms FAUTO added (flagged '&' in a model file).
        names, values, sigmas, units: the fitted parameters (internal units, radians).
        n_obs: stars fitted; sky_rms, popn_sd: the final fit's, radians.
        mimics: ``(candidate, term in the model, r)`` for candidates left out because
            they mimic a term in the model (first time seen).
        outliers: ``(row, on-sky residual in radians)`` of the weak outlier candidates,
            rows numbered from 0 in the observations given (weight-0 rows counted).
        correlated: ``(name, name, r)`` of fitted parameter pairs with ``|r| >=``
            ``correlated`` (not reliably distinguished).
        rules: the rules used, in words.
    """

    model: Model
    steps: tuple[FautoStep, ...]
    added: tuple[str, ...]
    names: tuple[str, ...]
    values: np.ndarray
    sigmas: np.ndarray
    units: tuple[str, ...]
    n_obs: int
    sky_rms: float
    popn_sd: float
    mimics: tuple[tuple[str, str, float], ...]
    outliers: tuple[tuple[int, float], ...]
    correlated: tuple[tuple[str, str, float], ...]
    rules: str

    def report(self) -> str:
        """The step table (arcsec), the final model, outlier candidates and correlated pairs."""
        width = max(10, *(len(s.term) for s in self.steps if s.action != "start"), 4)
        head = f"{'step':>4s}  {'stage':<9s} {'action':<6s} {'term':<{width}s} {'M':>3s} {'Sky RMS':>9s} {'Popn SD':>9s} {'|v/sig|':>8s}"
        lines = [f"FAUTO ({self.rules})", "", head, "-" * len(head)]
        for k, s in enumerate(self.steps):
            sig = "" if s.action == "start" else f"{s.significance:8.1f}"
            term = "" if s.action == "start" else s.term
            lines.append(
                f"{k:4d}  {s.stage:<9s} {s.action:<6s} {term:<{width}s} {s.n_terms:3d} {s.sky_rms / ARCSEC:9.3f} "
                f"{s.popn_sd / ARCSEC:9.3f} {sig:>8s}"
            )
        lines += ["", f"start: {self.steps[0].term}", f"final model: {len(self.names)} terms, N {self.n_obs}, "
                  f"Sky RMS {self.sky_rms / ARCSEC:.3f}\", Popn SD {self.popn_sd / ARCSEC:.3f}\""]
        for n, v, s, u in zip(self.names, self.values, self.sigmas, self.units):
            scale = UNITS[u]
            flag = "&" if n in self.added else " "
            unit = "" if u == "arcsec" else f"  ({u})"
            lines.append(f" {flag}{n:<{width}s} {v / scale:+12.4f} {s / scale:11.4f}{unit}")
        if self.mimics:
            lines.append("not tried, mimic a term in the model: " + ", ".join(
                f"{c} ~ {t} (r {r:+.3f})" for c, t, r in self.mimics))
        if self.outliers:
            lines.append("weak outlier candidates (observation: on-sky residual): " + ", ".join(
                f"{i + 1}: {r / ARCSEC:.2f}\"" for i, r in self.outliers))
        if self.correlated:
            lines.append("cannot reliably be distinguished: " + ", ".join(
                f"{a}/{b} (r {r:+.3f})" for a, b, r in self.correlated))
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        return {
            "rules": self.rules,
            "n_obs": self.n_obs,
            "sky_rms_arcsec": finite_or_none(self.sky_rms / ARCSEC),
            "popn_sd_arcsec": finite_or_none(self.popn_sd / ARCSEC),
            "steps": [s.to_dict() for s in self.steps],
            "terms": [
                {"name": n, "value": finite_or_none(v / UNITS[u]), "sigma": finite_or_none(s / UNITS[u]),
                 "unit": u, "added": n in self.added}
                for n, v, s, u in zip(self.names, self.values, self.sigmas, self.units)
            ],
            "mimics": [{"candidate": c, "term": t, "r": r} for c, t, r in self.mimics],
            "outliers": [{"observation": i + 1, "residual_arcsec": r / ARCSEC} for i, r in self.outliers],
            "correlated": [{"a": a, "b": b, "r": r} for a, b, r in self.correlated],
        }

    def model_file_terms(self):
        """The final model as :class:`pointax.io.tpoint_model.ModelTerm` s (arcsec), FAUTO's
        additions flagged '&', fixed terms '='."""
        from ..io.tpoint_model import ModelTerm

        sigma = dict(zip(self.names, self.sigmas))
        out = []
        for p in self.model.parameters:
            s = sigma.get(p.name)
            out.append(ModelTerm(p.name, float(self.model.get(p.name)) / ARCSEC,
                                 None if s is None else float(s) / ARCSEC,
                                 fixed=p.name in self.model.fixed, parallel=p.name in self.added))
        return out

    def write_model(self, path, caption: str = "pointax FAUTO", refraction=(0.0, 0.0)) -> None:
        """Write the final model as a TPOINT model file, with N, Sky RMS and sigmas, and
        FAUTO's additions flagged '&' (:func:`pointax.io.tpoint_model.format_model`)."""
        from pathlib import Path

        from ..io.tpoint_model import format_model

        text = format_model(self.model_file_terms(), caption, self.n_obs, self.sky_rms / ARCSEC, refraction, "lines")
        Path(path).write_text(text)


def _popn_sd(sky_rms: float, n: int, m: int) -> float:
    """TPOINT's Popn SD = Sky RMS sqrt(N / (N - M)); NaN when N <= M."""
    return sky_rms * math.sqrt(n / (n - m)) if n > m else math.nan


def _correlations(jac: np.ndarray, cols: Sequence[int]) -> np.ndarray | None:
    """Parameter correlations ``C_ij / sqrt(C_ii C_jj)`` of ``C = (J^T J)^-1`` over ``cols``
    (columns scaled to unit length first, which leaves the correlations as they are and
    keeps the inverse well conditioned); None when the columns are linearly dependent
    (a correlation of 1 in effect)."""
    a = jac[:, list(cols)]
    norms = np.linalg.norm(a, axis=0)
    if np.any(norms == 0) or not np.all(np.isfinite(a)):
        return None
    a = a / norms
    if np.linalg.matrix_rank(a, tol=1e-10) < a.shape[1]:
        return None
    cov = np.linalg.inv(a.T @ a)
    with np.errstate(invalid="ignore"):  # a negative variance (near dependence): NaN, None below
        d = np.sqrt(np.diag(cov))
        r = cov / np.outer(d, d)
    if not np.all(np.isfinite(r)) or np.max(np.abs(r)) > 1 + 1e-6:
        return None
    return np.clip(r, -1.0, 1.0)


def _without(state: FitState, term: int, columns: Sequence[int]) -> FitState:
    """``state`` without ``term`` (its parameters ``columns`` set to 0), linearised at
    ``state``'s fit rather than refitted: the origin's residuals move by the Jacobian
    there times the values taken out. What an exchange screens candidates from: one
    refit per term in the model would be a full Jacobian each Gauss-Newton step."""
    jac, r, y = (np.asarray(a) for a in state.origin)
    cols = list(columns)
    shift = np.einsum("bkc,bc->bk", jac[:, :, cols], y[:, cols]).reshape(r.shape)
    y = y.copy()
    y[:, cols] = 0.0
    # The figures of a fit it is not: NaN, so that nothing reads the full model's as its own.
    return dataclasses.replace(state, active=state.active - {term}, y=y[0], r=np.full_like(state.r, math.nan),
                               sigmas=np.full_like(state.sigmas, math.nan), rms_in=math.nan, rms_out=math.nan,
                               sky_rms=math.nan, n_params=state.n_params - len(cols),
                               origin=jax.device_put((jac, r - shift, y)))


class _Search:
    """The state of one FAUTO search over a superset (:class:`Builder`)."""

    def __init__(self, builder: Builder, params, names: list[str], n_obs: int, collinearity: float):
        self.b, self.params, self.names, self.n, self.collinearity = builder, params, names, n_obs, collinearity
        self.mimics: dict[str, tuple[str, str, float]] = {}
        self._jacobian: tuple[FitState, np.ndarray] | None = None

    def popn(self, state: FitState) -> float:
        return _popn_sd(state.sky_rms, self.n, state.n_params)

    def jacobian(self, state: FitState) -> np.ndarray:
        """The fitted rows' Jacobian at ``state``'s values; the last state's is kept, as
        the forward search's last screen, the exchange after it and the final report
        all ask for the same state's."""
        if self._jacobian is None or self._jacobian[0] is not state:
            rows = np.repeat(self.b.scheme.fit_rows, 2)
            self._jacobian = (state, self.b.linearise(state.y)[1][rows])
        return self._jacobian[1]

    def screen_all(self, state: FitState, ts: Sequence[int], jac: np.ndarray) -> dict[int, tuple[float, float] | None]:
        """:meth:`screen` of every candidate of ``ts`` (in order: the first mimic seen is
        the one reported), those of one parameter together in NumPy: the same
        linearised step, as a partitioned least-squares problem (the candidate's column
        made orthogonal to the model's), and the same correlations, from the inverse of
        the model's normal matrix. One screen of a few hundred candidates then costs a
        few small matrix products instead of a compiled step each."""
        singles = [t for t in ts if len(self.b.columns[t]) == 1]
        out: dict[int, tuple[float, float] | None] = {t: None for t in ts}
        free = self.b.mask(state.active)
        m_new = int(free.sum()) + 1
        if singles and self.n - m_new >= 1:
            got = self._screen_singles(state, singles, jac, free, m_new)
        else:
            got = {}
        for t in ts:
            if t in got:
                out[t] = got[t]
            elif len(self.b.columns[t]) != 1:
                out[t] = self.screen(state, t, jac)
        return out

    def _screen_singles(self, state, singles, jac, free, m_new):
        old = np.flatnonzero(free)
        cand = np.array([self.b.columns[t][0] for t in singles])
        got: dict[int, tuple[float, float] | None] = {}
        # Correlations (at the fit's values): unit columns, C = (A^T A)^-1 of the model's,
        # g = C A^T c, |c_perp|^2 = 1 - c^T A g, r(a_i, c) = -g_i / sqrt(|c_perp|^2 C_ii + g_i^2).
        a = jac[:, old]
        c = jac[:, cand]
        a_norm = np.linalg.norm(a, axis=0)
        c_norm = np.linalg.norm(c, axis=0)
        usable = (c_norm > 0) & np.all(np.isfinite(c), axis=0)
        if not (np.all(a_norm > 0) and np.all(np.isfinite(a))) or (
            len(old) and np.linalg.matrix_rank(a / a_norm, tol=1e-10) < len(old)
        ):
            corr, apart = None, np.zeros(len(singles), bool)
        else:
            an = a / a_norm
            cn = np.where(usable, c, 0.0) / np.where(usable, c_norm, 1.0)
            cov = np.linalg.inv(an.T @ an) if len(old) else np.zeros((0, 0))
            g = cov @ (an.T @ cn)
            perp2 = 1.0 - np.sum(cn * (an @ g), axis=0)
            apart = usable & (perp2 > 1e-20)
            with np.errstate(invalid="ignore", divide="ignore"):
                corr = -g / np.sqrt(np.maximum(perp2, 0.0)[None, :] * np.diag(cov)[:, None] + g**2)
        # The linearised step from the fit's origin: partitioned least squares.
        rows = np.repeat(self.b.scheme.fit_rows, 2)
        jac0 = np.asarray(state.origin[0])[0][rows]
        r0 = np.asarray(state.origin[1])[0][self.b.scheme.fit_rows].reshape(-1)
        q = np.linalg.qr(jac0[:, old])[0] if len(old) else np.zeros((len(r0), 0))
        r_perp = r0 - q @ (q.T @ r0)
        c0 = jac0[:, cand]
        c_perp = c0 - q @ (q.T @ c0)
        norm2 = np.sum(c_perp**2, axis=0)
        with np.errstate(invalid="ignore", divide="ignore"):
            proj = c_perp.T @ r_perp
            sky = np.sqrt(np.maximum(r_perp @ r_perp - proj**2 / norm2, 0.0) / self.n)
            z = np.abs(proj) / (np.sqrt(norm2) * sky)
        for k, t in enumerate(singles):
            name = self.names[t]
            if corr is None or not apart[k] or not np.all(np.isfinite(corr[:, k])):
                self.mimics.setdefault(name, (name, "the model's terms together", 1.0))
                continue
            if len(old):
                i = int(np.argmax(np.abs(corr[:, k])))
                if abs(corr[i, k]) > self.collinearity:
                    partner = self.params[old[i]]
                    self.mimics.setdefault(name, (name, self.names[partner.term], float(corr[i, k])))
                    continue
            if not (np.isfinite(z[k]) and norm2[k] > 0):
                continue
            got[t] = (float(z[k]), _popn_sd(float(sky[k]), self.n, m_new))
        return got

    def twins(self, state: FitState, ts: Sequence[int], other: int, jac: np.ndarray) -> set[int]:
        """The terms of ``ts`` whose columns, made orthogonal to ``state``'s model, have a
        correlation above the collinearity bar with a column of ``other`` (so made too):
        in a fit of the model with both, they could not be told apart (the parameter
        correlation is minus this partial correlation)."""
        free = np.flatnonzero(self.b.mask(state.active))
        q = np.linalg.qr(jac[:, free])[0] if len(free) else np.zeros((len(jac), 0))

        def unit_perp(cols):
            c = jac[:, cols]
            c = c - q @ (q.T @ c)
            norm = np.linalg.norm(c, axis=0)
            return c / np.where(norm > 0, norm, 1.0), norm > 0

        o, o_ok = unit_perp(self.b.columns[other])
        out = set()
        for t in ts:
            c, c_ok = unit_perp(self.b.columns[t])
            r = np.abs(c.T @ o)[np.ix_(c_ok, o_ok)]
            if r.size and r.max() > self.collinearity:
                out.add(t)
        return out

    def screen(self, state: FitState, t: int, jac: np.ndarray) -> tuple[float, float] | None:
        """``(|value/sigma|, Popn SD)`` with ``t`` added (one linearised step), or None when
        it cannot be determined or mimics a term in the model."""
        free = self.b.mask(state.active | {t})
        cols_new = self.b.columns[t]
        if self.n - int(free.sum()) < 1:
            return None
        cols = list(np.flatnonzero(free))
        r = _correlations(jac, cols)
        if r is None:
            name = self.names[t]
            self.mimics.setdefault(name, (name, "the model's terms together", 1.0))
            return None
        new = [cols.index(c) for c in cols_new]
        old = [k for k in range(len(cols)) if k not in new]
        if old:
            sub = np.abs(r[np.ix_(new, old)])
            k = np.unravel_index(int(np.argmax(sub)), sub.shape)
            if sub[k] > self.collinearity:
                partner = self.params[cols[old[k[1]]]]
                name = self.names[t]
                self.mimics.setdefault(name, (name, self.names[partner.term], float(r[new[k[0]], old[k[1]]])))
                return None
        s = _steps_program()(*state.origin, jax.device_put(free), self.b.rows)
        sig = np.asarray(s.sigmas)[0, cols_new]
        if np.any(~np.isfinite(sig)) or np.any(sig <= 0):
            return None
        z = float(np.max(np.abs(np.asarray(s.values)[0, cols_new] / sig)))
        return z, _popn_sd(float(np.asarray(s.sky_rms)[0]), self.n, int(free.sum()))


def _start_model(data, start, kind_hint, form):
    """The start model and the mount kind."""
    if isinstance(start, Model):
        return start, _mount_kind(start.mount)
    if start is not None and not isinstance(start, str):
        raise TypeError(f"start must be a pointax.Model, term names or None, got {type(start).__name__}")
    probe = family_model("basic", data, form=form) if kind_hint is None else None
    kind = kind_hint or _mount_kind(probe.mount)
    names = start if start is not None else " ".join(FAUTO_PHYSICAL[kind][0])
    return family_model(names, data, form=form), kind


@float64
def fauto(
    data,
    *,
    start: Model | str | None = None,
    further: Iterable[str] | None = None,
    max_order: int = 8,
    max_product_order: int = 0,
    harmonics: Iterable[str] | None = None,
    significance: float = 2.0,
    collinearity: float = 0.99,
    start_rule: str = "popn",
    keep_start: bool | None = None,
    outlier_sigmas: float = 3.0,
    correlated: float = 0.95,
    form: str = "rigorous",
    exchanges: bool = True,
) -> Fauto:
    """TPOINT-style automatic model building (FAUTO; the module docstring gives the rule).

    Args:
        data: the observations (alt-az or X-Y), or a TPOINT run (:func:`pointax.io.read_tpoint`;
            an equatorial run gives its latitude). Observations at weight 0 are left out.
        start: the start model (a :class:`pointax.Model`) or term names; default the
            mount's basic physical terms (:data:`FAUTO_PHYSICAL`: alt-az IA IE CA NPAE AN
            AW TF TX, equatorial IH ID CH NP MA ME TF, X-Y the basic family).
        further: further physical terms tried first (default :data:`FAUTO_PHYSICAL`'s).
        max_order: highest harmonic order tried (:func:`harmonic_candidates`; default 8,
            the highest order in TPOINT's FAUTO models, ``benchmarks/fauto_notes.md``).
        max_product_order: two-coordinate product harmonics (:func:`product_candidates`,
            both orders to this, ``12 max_product_order^2`` names) are tried in a last
            stage, with the single harmonics still open (default 0: none; order 4
            helped one real run and broke another's term target,
            ``benchmarks/fauto_notes.md``; X-Y mounts have none).
        harmonics: harmonic names to try instead (all in the first harmonic stage).
        significance: the ``|value / sigma|`` a term needs to be added and to stay (default 2).
        collinearity: a candidate whose parameter correlation with a term in the model
            exceeds this in absolute value is not tried (default 0.99).
        start_rule: when a start term is dropped (it is not tried again):
            'popn' (default): the least significant start term is dropped when the
            refit without it has the lower Popn SD (for a linear problem: ``|value /
            sigma| < sqrt(N / (N - M))``), one at a time, at the start and after every
            addition, as TPOINT's FAUTO holds insignificant basic terms at 0;
            'significance': like an added term, when ``|value / sigma| < significance``
            (drops correlated planted terms on a simulated run); 'never'.
        keep_start: the older switch: True is ``start_rule='never'``, False
            ``start_rule='significance'``.
        outlier_sigmas: observations whose on-sky residual exceeds this many Popn SD are
            reported as weak outlier candidates (default 3).
        correlated: fitted pairs with ``|r|`` at least this are reported (default 0.95).
        form: 'rigorous' (default) or 'linear' TPOINT term forms.
        exchanges: after the last stage, swap an added term for an open candidate
            while a swap lowers Popn SD (then add again), as the module docstring says
            (default True; False: the forward search alone).

    Returns:
        :class:`Fauto`; ``print(result.report())``; ``result.write_model(path)``.
    """
    if not (math.isfinite(significance) and significance > 0 and 0 < collinearity <= 1):
        raise ValueError(f"significance must be > 0 and 0 < collinearity <= 1, got {significance!r}, {collinearity!r}")
    for label, value in (("max_order", max_order), ("max_product_order", max_product_order)):
        if int(value) != value or value < 0:
            raise ValueError(f"{label} must be a whole number >= 0, got {value!r}")
    if keep_start is not None:
        start_rule = "never" if keep_start else "significance"
    if start_rule not in ("popn", "significance", "never"):
        raise ValueError(f"start_rule must be 'popn', 'significance' or 'never', got {start_rule!r}")
    obs = getattr(data, "observations", data)
    kind_hint = "equatorial" if getattr(data, "mount", None) == "equatorial" else None
    scheme = evaluation_scheme(obs, None, None, 0)
    in_use = np.flatnonzero(np.asarray(as_observations(obs).weight) > 0)  # rows of ``data`` fitted
    start_model, kind = _start_model(data, start, kind_hint, form)
    in_start = {t.name for t in start_model.terms}
    stages: list[tuple[str, list[str]]] = []
    physical = list(FAUTO_PHYSICAL[kind][1] if further is None else further)
    stages.append(("physical", [n for n in physical if n not in in_start]))
    if harmonics is not None:
        stages.append(("harmonic", [n for n in harmonics if n not in in_start]))
    elif max_order >= 1:
        names = [n for k in range(1, int(max_order) + 1) for n in harmonic_candidates(kind, k)]
        stages.append(("harmonic", [n for n in names if n not in in_start]))
    if max_product_order >= 1 and harmonics is None:
        stages.append(("product", [n for n in product_candidates(kind, int(max_product_order)) if n not in in_start]))
    pool = [n for _, names in stages for n in names]
    if len(set(pool)) != len(pool):
        raise ValueError("a candidate is named twice")
    extra = family_model(pool, start_model.mount, form=form).terms if pool else ()
    superset = start_model.with_terms(*extra)
    superset = superset.set(**{p.name: 0.0 for p in superset.parameters[len(start_model.parameters):]})
    cos2 = second_axis_cosines(start_model.mount, scheme.obs, resolve_per_axis(start_model.mount, None))
    builder = Builder(superset, scheme, cos2)
    names = [t.name for t in superset.terms]
    n_start = len(start_model.terms)
    index = {n: i for i, n in enumerate(names)}
    search = _Search(builder, superset.parameters, names, scheme.n_fit, collinearity)
    kept = set(range(n_start)) if start_rule != "significance" else set()

    state = builder.state(frozenset(i for i in range(n_start) if builder.columns.get(i)), builder.y_start)
    steps = [FautoStep("start", "start", " ".join(names[:n_start]), state.n_params, state.sky_rms,
                       search.popn(state), math.nan)]
    barred: set[int] = set()

    def drop_weak(state: FitState, stage: str) -> FitState:
        """While a term that may be dropped has ``|value / sigma| < significance``, drop
        the least significant one (it is not tried again) and refit."""
        while True:
            z = {t: builder.significance(state, t) for t in sorted(state.active - kept)}
            weak = [t for t in z if z[t] < significance]
            if not weak:
                return state
            t = min(weak, key=lambda k: (z[k], k))
            barred.add(t)
            state = builder.state(state.active - {t}, state.y)
            steps.append(FautoStep(stage, "drop", names[t], state.n_params, state.sky_rms, search.popn(state), z[t]))

    def drop_start(state: FitState, stage: str) -> FitState:
        """start_rule 'popn': while the refit without the least significant start term
        has the lower Popn SD, drop it (it is not tried again)."""
        while start_rule == "popn":
            z = {t: builder.significance(state, t) for t in sorted(state.active & kept)}
            if not z:
                return state
            t = min(z, key=lambda k: (z[k], k))
            trial = builder.state(state.active - {t}, state.y)
            if not search.popn(trial) < search.popn(state):
                return state
            barred.add(t)
            state = trial
            steps.append(FautoStep(stage, "drop", names[t], state.n_params, state.sky_rms, search.popn(state), z[t]))
            state = drop_weak(state, stage)
        return state

    def best_addition(state: FitState, bar: float, twin_of: int | None = None,
                      jac: np.ndarray | None = None) -> tuple[int, float] | None:
        """The open candidate (not barred; not ``twin_of`` nor a term it cannot be told
        apart from, :meth:`_Search.twins`) whose addition to ``state`` gives the lowest
        Popn SD below ``bar`` at ``|value / sigma| >= significance``, with that Popn SD
        (linearised), or None. ``jac``: the Jacobian to screen with (default: at
        ``state``'s values)."""
        trying = [t for t in open_ids if t not in state.active and t not in barred]
        jac = search.jacobian(state) if jac is None else jac
        if twin_of is not None:
            trying = [t for t in trying if t != twin_of]
            trying = [t for t in trying if t not in search.twins(state, trying, twin_of, jac)]
        screened = search.screen_all(state, trying, jac)
        best = None
        for t in trying:
            got = screened[t]
            if got is None or got[0] < significance or not got[1] < bar:
                continue
            if best is None or got[1] < best[1]:
                best = (t, got[1])
        return best

    def forward(state: FitState, stage: str) -> FitState:
        """Add the best candidate, then drop what lost significance, while one lowers Popn SD."""
        while (best := best_addition(state, search.popn(state))) is not None:
            state = builder.state(state.active | {best[0]}, state.y)
            steps.append(FautoStep(stage, "add", names[best[0]], state.n_params, state.sky_rms, search.popn(state),
                                   builder.significance(state, best[0])))
            state = drop_start(drop_weak(state, stage), stage)
        return state

    def exchange(state: FitState) -> FitState | None:
        """The swap of an added term for an open candidate that lowers Popn SD most
        (each added term left out in turn, the candidates screened on the model without
        it, linearised at ``state``'s fit; never a candidate the left-out term cannot be
        told apart from), the swapped-out term barred; None when no swap lowers Popn SD
        in the refits."""
        current = search.popn(state)
        mimics = dict(search.mimics)  # the screens of the reduced models report no mimics
        jac = search.jacobian(state)
        best = None  # (popn, out, candidate)
        for out in sorted(state.active - kept):
            reduced = _without(state, out, builder.columns[out])
            got = best_addition(reduced, current if best is None else best[0], twin_of=out, jac=jac)
            if got is not None:
                best = (got[1], out, got[0])
        search.mimics = mimics
        if best is None:
            return None
        _, out, t = best
        reduced = builder.state(state.active - {out}, state.y)
        trial = builder.state(reduced.active | {t}, reduced.y)
        if not search.popn(trial) < current:
            return None
        barred.add(out)
        steps.append(FautoStep("exchange", "drop", names[out], reduced.n_params, reduced.sky_rms, search.popn(reduced),
                               builder.significance(state, out)))
        steps.append(FautoStep("exchange", "add", names[t], trial.n_params, trial.sky_rms, search.popn(trial),
                               builder.significance(trial, t)))
        return drop_start(drop_weak(trial, "exchange"), "exchange")

    state = drop_start(drop_weak(state, "start"), "start")
    open_ids: list[int] = []
    for stage, stage_names in stages:
        open_ids += [index[n] for n in stage_names if builder.columns.get(index[n])]
        state = forward(state, stage)
    while exchanges and (swapped := exchange(state)) is not None:
        state = forward(swapped, "exchange")
    result = _result(builder, superset, start_model, state, steps, search, n_start, kept, outlier_sigmas, correlated,
                     significance, collinearity, start_rule, max_order, max_product_order, exchanges)
    return dataclasses.replace(result, outliers=tuple((int(in_use[i]), r) for i, r in result.outliers))


_START_RULES = {
    "never": " (start terms kept)",
    "significance": " (start terms too)",
    "popn": ", a start term when Popn SD falls without it",
}


def _result(builder, superset, start_model, state, steps, search, n_start, kept, outlier_sigmas, correlated,
            significance, collinearity, start_rule, max_order, max_product_order, exchanges) -> Fauto:
    names = search.names
    final = [i for i in range(len(superset.terms)) if i in state.active or (i < n_start and not builder.columns.get(i))]
    fitted = superset.with_values(jax.device_put(state.y))
    model = start_model.restructured(terms=[fitted.terms[i] for i in final])
    cols = list(np.flatnonzero(builder.mask(state.active)))
    params = superset.parameters
    popn = search.popn(state)
    rows = np.flatnonzero(builder.scheme.fit_rows)
    on_sky = np.hypot(state.r[rows, 0], state.r[rows, 1])
    outliers = tuple((int(i), float(r)) for i, r in zip(rows, on_sky) if math.isfinite(popn) and r > outlier_sigmas * popn)
    pairs = []
    r = _correlations(search.jacobian(state), cols)
    if r is not None:
        for a in range(len(cols)):
            for b in range(a + 1, len(cols)):
                if abs(r[a, b]) >= correlated:
                    pairs.append((params[cols[a]].name, params[cols[b]].name, float(r[a, b])))
    added = tuple(names[i] for i in sorted(state.active) if i >= n_start)
    rules = (
        f"add: |value/sigma| >= {significance:g} and Popn SD falls, no |r| > {collinearity:g} with a term in; "
        f"drop: |value/sigma| < {significance:g}{_START_RULES[start_rule]}; "
        f"harmonics to order {max_order}"
        f"{f', products to order {max_product_order}' if max_product_order else ''}"
        f"{'; then exchanges while Popn SD falls' if exchanges else ''}; pointax's rule"
    )
    return Fauto(
        model=model,
        steps=tuple(steps),
        added=added,
        names=tuple(params[c].name for c in cols),
        values=state.y[cols],
        sigmas=state.sigmas[cols],
        units=tuple(params[c].unit for c in cols),
        n_obs=search.n,
        sky_rms=state.sky_rms,
        popn_sd=popn,
        mimics=tuple(search.mimics.values()),
        outliers=outliers,
        correlated=tuple(pairs),
        rules=rules,
    )
