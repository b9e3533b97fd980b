"""The TPOINT commands a session runs, one function each: ``command(session, args, line)``.

Each takes the :class:`~pointax.procedures.session.Session`, the arguments as written
and the :class:`~pointax.procedures.parser.Line` (for relative file names), changes
the session and prints what TPOINT would. PROC, RETURN, INPRO, CALL, END, EXIT and
QUIT are the runner's (:mod:`pointax.procedures.runner`); the graphics commands (G...,
GC, CAPT, PLTZ) are in :mod:`pointax.procedures.graphics`. Display settings
(:data:`~pointax.procedures.parser.NOTED_SETTINGS`) and TPOINT commands pointax does not
run (:data:`~pointax.procedures.parser.NOT_IMPLEMENTED`) print a one-line note.
"""

from __future__ import annotations

import math
import re

import numpy as np

from ..core.units import ARCSEC
from .graphics import cmd_capt, cmd_gc, cmd_graph, cmd_pltz, require_fit
from .parser import COMMANDS, NOT_IMPLEMENTED, NOTED_SETTINGS, Line, Quoted
from .session import Session, read_run

__all__ = ["COMMAND_FUNCTIONS", "LIGHT_COMMANDS", "DEFAULT_FAUTO_CANDIDATES", "EQUATORIAL_FAUTO_CANDIDATES", "fit_table"]

DEFAULT_FAUTO_CANDIDATES = tuple(
    f"H{what}{fn}{arg}{k}" for what in "AES" for fn in "SC" for arg in "AE" for k in (1, 2, 3)
)
"""FAUTO CV's candidates when none are named, alt-az runs: TPOINT harmonics of A, E and S
(cross-elevation) in sin and cos of azimuth and elevation, multipliers 1 to 3 (36 terms)."""

EQUATORIAL_FAUTO_CANDIDATES = tuple(
    f"H{what}{fn}{arg}{k}" for what in "HDX" for fn in "SC" for arg in "HD" for k in (1, 2, 3)
)
"""FAUTO CV's candidates when none are named, equatorial runs: harmonics of H, D and X
(cross-declination) in sin and cos of hour angle and declination, multipliers 1 to 3."""


def _names(args: list[str], what: str) -> list[str]:
    from ..terms import names

    out = names(" ".join(args))
    if not out:
        raise ValueError(f"{what} needs term names")
    return out


def _check_terms(s: Session, names: list[str]) -> None:
    from ..terms import tpoint

    tpoint(names, form=s.form, **s.term_options())  # unknown names raise, listing the known ones


def cmd_indat(s: Session, args: list[str], line: Line) -> None:
    """INDAT FILE: read a pointing run (masks cleared; the model is kept)."""
    if len(args) != 1:
        raise ValueError("INDAT needs one file name")
    path = line.path(args[0])
    s.run = read_run(path, s.mount, s.azimuth)
    s.masked = np.zeros(len(s.run), bool)
    s.result, s.stale = None, True
    s.say(f"INDAT: {len(s.run)} observations from {path} ({s.run.caption})")


def cmd_inmod(s: Session, args: list[str], line: Line) -> None:
    """INMOD FILE: read a TPOINT model file: its terms, values and fixed terms replace
    the current model."""
    from ..io.tpoint_model import read_model

    if len(args) != 1:
        raise ValueError("INMOD needs one file name")
    path = line.path(args[0])
    mod = read_model(path)
    mod.check_terms(form=s.form, **s.term_options())  # unknown or other-mount terms: file and line
    names = [t.name.upper() for t in mod.terms]
    _check_terms(s, names)
    s.terms = names
    s.values = {n: v for n, v in zip(names, (t.value * ARCSEC for t in mod.terms))}
    s.fixed = {t.name.upper() for t in mod.terms if t.fixed}
    s.parallel = {t.name.upper() for t in mod.terms if t.parallel}
    s.refraction = mod.refraction
    s.stale = True
    s.say(f"INMOD: {len(names)} terms from {path}: {' '.join(names)}")


OUTMOD_LAYOUTS = {"ONELINE": "one-line", "LINES": "lines"}
"""OUTMOD's layout words after the file name: TPOINT's one-line layout, or a record a
line (the default)."""


def cmd_outmod(s: Session, args: list[str], line: Line) -> None:
    """OUTMOD FILE [ONELINE]: write the model as a TPOINT model file (with N, Sky RMS
    and sigmas of the last FIT when nothing changed since; the refraction constants of
    the model file INMOD read, else those of the run's weather); ONELINE writes TPOINT's
    one-line layout (with the x and y RMS and the masked observations of that FIT)."""
    from ..io.tpoint_model import refraction_arcsec, write_model

    layout = "lines"
    if len(args) == 2 and not isinstance(args[1], Quoted) and args[1].upper() in OUTMOD_LAYOUTS:
        layout = OUTMOD_LAYOUTS[args[1].upper()]
        args = args[:1]
    if len(args) != 1:
        raise ValueError(f"OUTMOD needs one file name, then optionally {' or '.join(OUTMOD_LAYOUTS)}")
    path = line.path(args[0])
    refraction = s.refraction or refraction_arcsec(s.run)  # INMOD's constants, else the run's weather
    shape = " (one-line layout)" if layout == "one-line" else ""
    if s.result is not None and not s.stale:
        write_model(path, s.result, caption=s.current_caption(), refraction=refraction, layout=layout, parallel=s.parallel)
        s.say(f"OUTMOD: {path}{shape} (N {int(s.result.n_obs)}, Sky RMS {float(s.result.sky_rms) / ARCSEC:.4f})")
    else:
        if not s.terms:
            raise ValueError("OUTMOD: the model has no terms (USE or INMOD first)")
        write_model(path, s.model(), caption=s.current_caption(), refraction=refraction, layout=layout, parallel=s.parallel)
        s.say(f"OUTMOD: {path}{shape} (values only: the model or the masks changed since the last FIT)")


def cmd_use(s: Session, args: list[str], line: Line) -> None:
    """USE NAME ...: add terms to the model (each starts at 0)."""
    names = _names(args, "USE")
    _check_terms(s, names)
    added = [n for n in names if n not in s.terms]
    for n in added:
        s.terms.append(n)
        s.values[n] = 0.0
    s.stale = s.stale or bool(added)
    already = [n for n in names if n not in added]
    s.say(f"USE: {' '.join(s.terms)}" + (f" ({' '.join(already)} already in use)" if already else ""))


def _in_use(s: Session, args: list[str], what: str) -> list[str]:
    """The terms ``args`` name, each in use; every term in use for ``ALL`` or for no
    argument (TPOINT's bare FIX, UNFIX and LOSE act on the whole model)."""
    if not args or [a.upper() for a in args] == ["ALL"]:
        return list(s.terms)
    names = _names(args, what)
    unknown = [n for n in names if n not in s.terms]
    if unknown:
        raise ValueError(f"{what}: {' '.join(unknown)} not in use (in use: {' '.join(s.terms) or 'none'})")
    return names


def cmd_lose(s: Session, args: list[str], line: Line) -> None:
    """LOSE [NAME ... | ALL]: remove terms from the model (all of them when none named)."""
    names = _in_use(s, args, "LOSE")
    s.terms = [n for n in s.terms if n not in names]
    for n in names:
        s.values.pop(n, None)
    s.fixed -= set(names)
    s.parallel -= set(names)
    s.stale = True
    s.say(f"LOSE: in use now {' '.join(s.terms) or 'none'}")


def cmd_fix(s: Session, args: list[str], line: Line) -> None:
    """FIX [NAME ... | ALL]: hold terms at their current values in FIT (all when none named)."""
    s.fixed |= set(_in_use(s, args, "FIX"))
    s.stale = True
    s.say(f"FIX: fixed {' '.join(n for n in s.terms if n in s.fixed) or 'none'}")


def cmd_unfix(s: Session, args: list[str], line: Line) -> None:
    """UNFIX [NAME ... | ALL]: fit terms again (all when none named)."""
    s.fixed -= set(_in_use(s, args, "UNFIX"))
    s.stale = True
    s.say(f"UNFIX: fixed {' '.join(n for n in s.terms if n in s.fixed) or 'none'}")


ADJUST_DIRECTIONS = {
    "T": "the model adjusts the telescope to fit the stars (observed = raw + model): pointax's direction",
    "S": "the model adjusts the stars to fit the telescope",
}
"""TPOINT's ADJUST settings: which side of the comparison the model moves."""


def cmd_adjust(s: Session, args: list[str], line: Line) -> None:
    """ADJUST T|S: the direction of the model. T (telescope to fit the stars) is
    pointax's, the one whose coefficients DESIGN's TPOINT conformance checks; S (stars
    to fit the telescope) is noted and not applied."""
    if not args:
        s.say(f"ADJUST: T, {ADJUST_DIRECTIONS['T']}")
        return
    which = args[0].upper()
    if len(args) != 1 or which not in ADJUST_DIRECTIONS:
        raise ValueError(f"takes T or S, got {' '.join(args)}")
    if which == "T":
        s.say(f"ADJUST T: {ADJUST_DIRECTIONS['T']}")
    else:
        s.say(f"ADJUST S ({ADJUST_DIRECTIONS['S']}): not implemented; the model stays ADJUST T")


def fit_table(result, changes) -> str:
    """FIT's table: each fitted coefficient's change, value and sigma (arcsec), the
    fixed ones, Sky RMS, Popn SD and warnings."""
    lines = [f"       {'coeff':<9s}     change        value       sigma"]
    values, sigmas = np.asarray(result.values, np.float64), np.asarray(result.sigmas, np.float64)
    changes = np.asarray(changes, np.float64)
    for k, (name, d, v, e) in enumerate(zip(result.names, changes, values, sigmas), 1):
        lines.append(f"  {k:3d}  {name:<9s} {d / ARCSEC:+10.4f} {v / ARCSEC:+12.4f} {e / ARCSEC:11.4f}")
    for name in result.model.parameter_names:
        if name in result.model.fixed:
            lines.append(f"       {name:<9s} {'':10s} {float(result.model.get(name)) / ARCSEC:+12.4f}       fixed")
    popn = float(result.popn_sd) / ARCSEC
    lines += ["", f"Sky RMS = {float(result.sky_rms) / ARCSEC:9.4f}"]
    lines.append(f"Popn SD = {popn:9.4f}" if math.isfinite(popn) else "Popn SD =   undefined")
    loo = float(getattr(result, "loo_rms", math.nan)) / ARCSEC
    if not math.isnan(loo):
        lines.append(f"LOO RMS = {loo:9.4f}" if math.isfinite(loo) else "LOO RMS =   undefined")
    lines += [f"WARNING: {w}" for w in result.warnings() if "did not converge" not in w]
    return "\n".join(lines)


def cmd_fit(s: Session, args: list[str], line: Line) -> None:
    """FIT: one linearised adjustment of the free coefficients from their current
    values (:func:`pointax.procedures.step.gauss_newton_step`); prints the changes."""
    from .step import gauss_newton_step

    if args:
        raise ValueError(f"FIT takes no arguments, got {' '.join(args)}")
    run = s.require_run()
    if not s.terms:
        raise ValueError("FIT: the model has no terms (USE or INMOD first)")
    step = gauss_newton_step(s.model(), run, weights=s.weights(), caption=s.current_caption())
    result = step.result
    for name in s.terms:
        s.values[name] = float(result.model.get(name))
    s.result, s.stale = result, False
    n_masked = int(s.masked.sum())
    s.say(
        f"FIT: one linearised adjustment, {len(result.names)} coefficients, {int(result.n_obs)} observations"
        + (f" ({n_masked} masked)" if n_masked else "")
    )
    s.say()
    s.say(fit_table(result, step.changes))


def cmd_slist(s: Session, args: list[str], line: Line) -> None:
    """SLIST: the residual listing of the last FIT (masks as they are now)."""
    from ..analysis.listing import format_listing

    result = require_fit(s, "SLIST")
    if s.stale:
        s.say("SLIST: the model or the masks changed since the last FIT; residuals and 'used' are that FIT's")
    s.say(format_listing(s.run, result, s.masked))


_R_ABOVE = re.compile(r"^R\s*(>|GT)\s*([-+0-9.eE]+)$", re.IGNORECASE)


def cmd_mask(s: Session, args: list[str], line: Line) -> None:
    """MASK R > X: mask observations whose on-sky residual under the current model
    exceeds X arcsec; MASK 17 19-21: by number (from 1, file order); MASK ALL."""
    from ..fitting.masking import format_rows, mask_above, parse_rows

    run = s.require_run()
    text = " ".join(args).strip()
    if not text:
        raise ValueError("MASK needs R > X (arcsec) or observation numbers (17 19-21)")
    before = s.masked.copy()
    match = _R_ABOVE.match(text)
    if match:
        limit = float(match.group(2))
        if not s.terms:
            raise ValueError("MASK R > X judges residuals of the model: USE or INMOD terms first")
        s.masked = mask_above(s.model(), run.observations, limit, masked=s.masked)
    elif text.upper() == "ALL":
        s.masked[:] = True
    elif text[0].isdigit() or text[0] == "-":
        s.masked[parse_rows(text, len(run), option="MASK")] = True
    else:
        raise ValueError(f"MASK {text}: pointax masks by R > X (on-sky residual, arcsec) or by observation number")
    new = np.flatnonzero(s.masked & ~before)
    s.stale = s.stale or bool(new.size)
    s.say(
        f"MASK: {new.size} more masked" + (f" ({format_rows(new)})" if new.size else "")
        + f"; {int(s.masked.sum())} masked, {int((~s.masked).sum())} in use"
    )


def cmd_unmask(s: Session, args: list[str], line: Line) -> None:
    """UNMASK: every observation in use again; UNMASK 17 19-21: those."""
    from ..fitting.masking import parse_rows

    run = s.require_run()
    text = " ".join(args).strip()
    if not text or text.upper() == "ALL":
        s.masked[:] = False
    else:
        s.masked[parse_rows(text, len(run), option="UNMASK")] = False
    s.stale = True
    s.say(f"UNMASK: {int(s.masked.sum())} masked, {int((~s.masked).sum())} in use")


def _fauto_start(s: Session):
    """FAUTO's start model: the terms in use, then the mount's basic physical terms not
    in use (:data:`pointax.analysis.FAUTO_PHYSICAL`), at their current values."""
    from ..analysis.fauto_search import FAUTO_PHYSICAL
    from ..terms import tpoint

    run = s.require_run()
    kind = "equatorial" if run.mount == "equatorial" else "altaz"
    names = list(s.terms) + [n for n in FAUTO_PHYSICAL[kind][0] if n not in s.terms]
    values = {n: s.values.get(n, 0.0) for n in names}
    terms = tpoint(names, form=s.form, values=values, **s.term_options())
    return run.model(terms, fixed=sorted(s.fixed), residual_form=s.residual_form)


def _fauto_cv(s: Session, names: list[str], rows: np.ndarray) -> None:
    """FAUTO CV: the cross-validated builder (:func:`pointax.build_model`) from the current model."""
    from ..analysis.model_building import build_model
    from ..terms import tpoint

    run = s.require_run()
    default = EQUATORIAL_FAUTO_CANDIDATES if run.mount == "equatorial" else DEFAULT_FAUTO_CANDIDATES
    names = names or [n for n in default if n not in s.terms]
    if not s.terms:
        raise ValueError("FAUTO CV builds from the current model: USE or INMOD terms first")
    candidates = tpoint(names, form=s.form, **s.term_options())
    build = build_model(candidates, run.observations[rows], start=s.model())
    s.say(build.report())
    s.terms = [t.name.upper() for t in build.model.terms]
    s.values = {n: float(build.model.get(n)) for n in s.terms}


def cmd_fauto(s: Session, args: list[str], line: Line) -> None:
    """FAUTO [NAME ...]: TPOINT-style automatic model building (:func:`pointax.analysis.fauto`):
    from the terms in use and the mount's basic physical terms, try the further physical
    terms, then harmonics to order 8 (or only the named candidates), keeping those with
    |value/sigma| >= 2 that lower Popn SD and mimic no term in the model, and dropping a
    start term when Popn SD falls without it (FAUTO NAME ...: only the named candidates are
    tried and the terms in use kept); prints the steps, weak outlier candidates and pairs
    not reliably distinguished, on the unmasked stars.
    FAUTO CV [NAME ...]: the cross-validated builder (:func:`pointax.build_model`) instead."""
    from ..analysis.fauto_search import fauto

    s.require_run()  # raises when no run is loaded
    rows = np.flatnonzero(s.observations().weight > 0)
    words = [str(a).upper() for a in args]
    if words[:1] == ["CV"]:
        _fauto_cv(s, _names(args[1:], "FAUTO CV") if len(args) > 1 else [], rows)
    else:
        named = _names(args, "FAUTO") if args else None
        if named:
            _check_terms(s, named)
        start = _fauto_start(s)
        chosen = None if named is None else [n for n in named if n not in {t.name for t in start.terms}]
        result = fauto(s.observations(), start=start, harmonics=chosen, further=() if named is not None else None,
                       start_rule="never" if named is not None else "popn", form=s.form)
        s.say(result.report())
        s.say("(& marks the terms FAUTO added)")
        s.terms = [t.name.upper() for t in result.model.terms]
        s.values = {n: float(result.model.get(n)) for n in s.terms}
        s.parallel = (s.parallel | {n.upper() for n in result.added}) & set(s.terms)
    s.fixed &= set(s.terms)
    s.stale = True


def cmd_show(s: Session, args: list[str], line: Line) -> None:
    """SHOW: the run, masks, terms with values (arcsec), fixed terms, last FIT."""
    if s.run is None:
        s.say("SHOW: no data (INDAT FILE)")
    else:
        s.say(f"data: {s.run.path} ({s.run.caption}), {len(s.run)} observations, {int(s.masked.sum())} masked")
        if s.masked.any():
            from ..fitting.masking import format_rows

            s.say(f"masked: {format_rows(np.flatnonzero(s.masked))}")
    mount = s.mount if s.run is None else s.run.mount  # the run's own mount once read
    where = f", azimuth {s.azimuth}" if mount != "equatorial" else ""
    s.say(f"mount: {mount}{where}; terms {s.form}, residuals {s.residual_form}")
    if not s.terms:
        s.say("model: no terms")
    for n in s.terms:
        s.say(f"  {n:<9s} {s.values.get(n, 0.0) / ARCSEC:+12.4f}" + ("  fixed" if n in s.fixed else ""))
    if s.result is not None:
        state = "changed since" if s.stale else "current"
        s.say(f"last FIT: Sky RMS {float(s.result.sky_rms) / ARCSEC:.4f}, N {int(s.result.n_obs)} ({state})")


def _noted(word: str):
    """The command of a display setting of :data:`NOTED_SETTINGS`: a note, no effect."""

    def cmd_noted(s: Session, args: list[str], line: Line) -> None:
        shown = f" ({' '.join(args)})" if args else ""
        s.say(f"{word}: display setting accepted{shown}; it changes nothing in pointax's plots")

    cmd_noted.__doc__ = f"{word}: TPOINT display setting, accepted with a note (no effect on pointax's plots)."
    return cmd_noted


def _skipped(word: str):
    """The command of a TPOINT command pointax does not run (:data:`NOT_IMPLEMENTED`):
    a one-line note naming it; the script goes on."""

    def cmd_skipped(s: Session, args: list[str], line: Line) -> None:
        s.say(f"{word}: TPOINT's command to {NOT_IMPLEMENTED[word]}: not implemented in pointax, skipped")

    cmd_skipped.__doc__ = f"{word}: TPOINT's command to {NOT_IMPLEMENTED[word]}; not implemented (a note)."
    return cmd_skipped


def cmd_help(s: Session, args: list[str], line: Line) -> None:
    """HELP [WORD]: the commands (or one of them): what pointax runs, the display
    settings it notes, and TPOINT's commands it does not implement. The texts are
    ``pointax/data/help/tpoint_commands.md``, the documentation site's too
    (:mod:`pointax.core.helptext`), printed whole, filled at spaces."""
    from ..core.helptext import fill, tpoint_entries
    from .parser import resolve

    entries = tpoint_entries()
    described = {w for words, _ in entries for w in words}
    # A command without an entry in the file: its docstring's first paragraph, whole.
    extra = [((w,), _first_paragraph(COMMAND_FUNCTIONS[w])) for w in COMMANDS if w not in described and w in COMMAND_FUNCTIONS]
    if args:
        word = resolve(args[0])
        word = "G..." if word == "G" else word
        entries = [e for e in entries + extra if word in e[0]] or [((word,), _RUNNER_HELP.get(word, ""))]
    else:
        entries = entries + extra
    for _, text in entries:
        s.say(fill(text, 88, indent="  ", subsequent="      "))


def _first_paragraph(fn) -> str:
    """The first paragraph of ``fn``'s docstring on one line, without reST markup."""
    paragraph = " ".join((fn.__doc__ or "").strip().split("\n\n")[0].split())
    return re.sub(r":\w+:`~?([^`]*)`", r"\1", paragraph).replace("``", "")


_RUNNER_HELP = {
    "PROC": "PROC NAME: define a procedure, up to RETURN",
    "RETURN": "end a procedure's definition",
    "INPRO": "INPRO FILE: read procedure definitions from a file",
    "CALL": "CALL NAME (or NAME alone): run a procedure",
    "END": "stop reading this file (or standard input)",
    "EXIT": "as END",
    "QUIT": "as END",
}

COMMAND_FUNCTIONS = {
    "INDAT": cmd_indat,
    "INMOD": cmd_inmod,
    "OUTMOD": cmd_outmod,
    "USE": cmd_use,
    "LOSE": cmd_lose,
    "FIX": cmd_fix,
    "UNFIX": cmd_unfix,
    "FIT": cmd_fit,
    "SLIST": cmd_slist,
    "MASK": cmd_mask,
    "UNMASK": cmd_unmask,
    "FAUTO": cmd_fauto,
    "SHOW": cmd_show,
    "ADJUST": cmd_adjust,
    "G": cmd_graph,
    "GC": cmd_gc,
    "CAPT": cmd_capt,
    "PLTZ": cmd_pltz,
    "HELP": cmd_help,
    **{word: _noted(word) for word in NOTED_SETTINGS},
    **{word: _skipped(word) for word in NOT_IMPLEMENTED},
}
"""Resolved command word (:func:`pointax.procedures.parser.resolve`) -> function."""

LIGHT_COMMANDS = frozenset({"HELP", "CAPT", "ADJUST", "PLTZ", *NOTED_SETTINGS, *NOT_IMPLEMENTED})
"""Commands that compute nothing (no JAX): :meth:`Session.ready` is not called for them."""
