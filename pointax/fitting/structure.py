"""Structure as data: which terms are in use and which parameters are free become arrays.

A pointing engineer changes the model all the time (TPOINT's USE, LOSE, FIX): each
change gives a model of another pytree structure, and a compiled fit is specialised to
its structure, so each would trace and compile the fit again (5-14 s). Here a model is
*embedded* in a larger one, a union of the terms seen for the same mount and residual
form: the terms the model lacks are present at their neutral values
(every parameter 0, which must leave the pointing unchanged: checked per term class)
and held fixed, and which parameters are free is a boolean array. Models of the same
family then share one structure, and so one compiled fit.

A model takes the most recently used of its family's unions that holds its terms
(its fit is the one compiled for the data at hand); when none
does, the most recent union grows by the model's new terms (that compiles once more)
if it holds at least half of them, or else, or when it would carry more than
:data:`MAX_EXTRA_TERMS` absent terms, the model gets a union of its own. Unions keep the terms in the order the models give them (rotations in
a chain do not commute), and a term that is not neutral at 0 is never carried by a
model that lacks it.
"""

from __future__ import annotations

import threading

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..core.model import Model
from ..core.term import Term, param_fields

__all__ = ["Embedding", "embed", "is_neutral", "clear"]

_PROBE_ANGLES = np.array([[0.3, 0.4], [2.1, 1.1], [-1.7, 0.2], [4.0, -0.6]])
_HOOKS = ("encoder_offset", "base_rotation", "axes_rotation", "boresight_rotation", "sky_offset")

_UNIONS: dict = {}  # family -> list of unions (tuples of terms), most recent first
_LOCK = threading.Lock()


class Embedding:
    """A model embedded in its family's union.

    Attributes:
        model: the union model, with the embedded model's values for its terms and 0 for
            the others (float64 NumPy leaves).
        free: ``(M_union,)`` which union parameters the fit adjusts: the embedded model's
            free parameters.
        index: ``(M_free,)`` where the embedded model's free parameters are in the union.
    """

    __slots__ = ("model", "free", "index")

    def __init__(self, model: Model, free: np.ndarray, index: np.ndarray):
        self.model, self.free, self.index = model, free, index


def _family(model: Model):
    return (type(model.mount), jax.tree.structure(model.mount), model.residual_form, model.sky_iterations)


def _identity(term: Term):
    return (term.name, type(term), jax.tree.structure(term))


def _zeroed(term: Term) -> Term:
    """``term`` with every parameter 0 (float64)."""
    out = term
    for f in param_fields(term):
        out = _set(out, f.name, np.zeros((), np.float64))
    return out


def _set(term, field, value):
    return eqx.tree_at(lambda t: getattr(t, field), term, value, is_leaf=lambda x: x is None)


def is_neutral(term: Term) -> bool:
    """Whether ``term`` with every parameter 0 leaves the pointing unchanged: as its class
    declares (:attr:`pointax.Term.neutral_at_zero`), else when each hook returns None, a
    zero offset or the identity rotation at a few probe angles."""
    _probe([term])
    return _NEUTRAL[_class_key(term)]


_NEUTRAL: dict = {}


def _class_key(term: Term):
    return (type(term), jax.tree.structure(term))  # the hooks depend on these alone


def _probe(terms) -> None:
    """Find which of ``terms`` are neutral at 0, for those not yet known: all of them in
    one compiled call (op by op, each new term cost a few small compilations, 40-230
    ms, at the first refit that left it out)."""
    new = {}
    for t in terms:
        key = _class_key(t)
        if key in _NEUTRAL or key in new:
            continue
        if t.neutral_at_zero is not None:  # declared (the library's are tested)
            _NEUTRAL[key] = bool(t.neutral_at_zero)
        else:
            new[key] = t
    for key, neutral in zip(new, _probe_values(list(new.values()))):
        _NEUTRAL[key] = neutral


def _probe_values(terms) -> list[bool]:
    """Whether each of ``terms`` (taken at every parameter 0) is neutral, computed at the
    probe angles in one compiled call."""
    if not terms:
        return []
    zeroed = [_zeroed(t) for t in terms]

    def outputs(a):
        return [[getattr(t, h)(a) for h in _HOOKS] for t in zeroed]

    try:
        with jax.enable_x64(True):
            got = jax.jit(jax.vmap(outputs))(jnp.asarray(_PROBE_ANGLES))
    except Exception:  # a term that cannot be evaluated at the probe angles: not neutral
        return [False] * len(terms)
    return [all(_is_nothing(out) for out in got[k]) for k in range(len(terms))]


def _is_nothing(out) -> bool:
    """Whether a hook's outputs at the probe angles leave the pointing unchanged."""
    if out is None:
        return True
    out = np.asarray(out, np.float64)
    want = np.broadcast_to(np.eye(3), out.shape) if out.shape[-2:] == (3, 3) else np.zeros(out.shape)
    return bool(np.array_equal(out, want))


def _merge(union: tuple[Term, ...], terms: tuple[Term, ...]) -> tuple[Term, ...]:
    """``terms`` in their order, with the neutral terms of ``union`` they lack inserted
    after the term that preceded them in ``union`` (a term of another kind under one of
    their names is dropped: names are unique in a model)."""
    ids = {_identity(t) for t in terms}
    names = {t.name for t in terms}
    _probe(union)
    out = list(terms)
    previous = None
    for t in union:
        key = _identity(t)
        if key in ids:
            previous = key
            continue
        if t.name in names or not is_neutral(t):
            continue
        at = 0 if previous is None else 1 + next(i for i, u in enumerate(out) if _identity(u) == previous)
        out.insert(at, t)
        previous = key
    return tuple(out)


def _is_subsequence(small: list, big: list) -> bool:
    it = iter(big)
    return all(any(x == y for y in it) for x in small)


MAX_EXTRA_TERMS = 16
"""A union carries at most this many terms beyond the model's own: past it, a model
gets a union of its own (one compilation) rather than paying for many absent terms in
every fit."""

MAX_UNIONS = 4
"""Unions kept per family (mount and residual form), the most recently used first."""


def _fits(union: tuple[Term, ...], model: Model) -> bool:
    """Whether ``model`` can be embedded in ``union`` as it is."""
    ids = [_identity(t) for t in model.terms]
    if not _is_subsequence(ids, [_identity(t) for t in union]):
        return False
    own, names = set(ids), {t.name for t in model.terms}
    extras = [t for t in union if _identity(t) not in own]
    if len(extras) > MAX_EXTRA_TERMS or any(t.name in names for t in extras):
        return False
    if extras:
        _probe(union)  # every term at once (one compilation), only once terms are absent
    return all(is_neutral(t) for t in extras)


def _shares_most(union: tuple[Term, ...], model: Model) -> bool:
    """Whether at least half of ``model``'s terms are in ``union``: a step of the
    USE / LOSE loop, not another model family (which gets a union of its own rather than
    making every fit of both compile and run with the other's terms)."""
    ids = {_identity(t) for t in union}
    return 2 * sum(_identity(t) in ids for t in model.terms) >= len(model.terms)


def embed(model: Model) -> Embedding:
    """Embed ``model`` in the most recently used of its family's unions that holds its
    terms, or in a new one: the most recent grown by the model's terms (a new
    structure: it compiles once; the unions it grew from stay, up to
    :data:`MAX_UNIONS`)."""
    key = _family(model)
    with _LOCK:
        unions = _UNIONS.setdefault(key, [])
        # The most recently used union that holds the model: the one whose fit is
        # compiled for the data at hand (a smaller one may not be).
        holding = next((u for u in unions if _fits(u, model)), None)
        if holding is not None:
            union = holding
            unions.remove(union)
        else:
            union = tuple(model.terms)
            if unions and _shares_most(unions[0], model):
                grown = _merge(unions[0], model.terms)
                if len(grown) - len(model.terms) <= MAX_EXTRA_TERMS:
                    union = grown
        unions.insert(0, union)
        del unions[MAX_UNIONS:]
    mine = {_identity(t): t for t in model.terms}
    terms = tuple(mine.get(_identity(t)) or _zeroed(t) for t in union)
    # The union's own Model: no fixed names (the mask says what is free).
    embedded = Model(model.mount, terms, (), model.sky_iterations, model.residual_form)
    owned = set(mine)
    free = np.array(
        [_identity(terms[p.term]) in owned and p.name not in model.fixed for p in embedded.parameters], bool
    )
    position = {p.name: k for k, p in enumerate(embedded.parameters)}
    index = np.array([position[p.name] for p in model.free_parameters], int)
    return Embedding(embedded, free, index)


def clear() -> None:
    """Forget every union (the next fit of each family starts a new one)."""
    with _LOCK:
        _UNIONS.clear()
