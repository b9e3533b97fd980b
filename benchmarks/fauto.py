"""pointax's FAUTO against TPOINT's on real runs with the model TPOINT's FAUTO wrote.

For every run/model pair (``RUN.dat`` beside ``RUN.mod`` or ``RUN.MOD``) in the folders
given with ``--pairs`` (and the repository's own runs with a TPOINT model: the bundled
MMT run, whose model is a plain 8-term fit, shown for reference), runs
:func:`pointax.analysis.fauto` on the run and prints per run: pointax's and TPOINT's term
count, N and Sky RMS, and the leave-one-out RMS (each star predicted by an explicit
refit on the others; on-sky, arcsec) of pointax's FAUTO model and of TPOINT's model's
terms fitted by pointax (the terms it holds fixed at 0 left out, and any term pointax
cannot build, named in the row). A model is TPOINT's FAUTO model when it flags terms
'&' or its file name says ``fauto``. Where TPOINT fitted fewer stars than the run holds
(its N), as many are left out, chosen by :func:`masked_like_tpoint`.
Targets (FAUTO pairs only): pointax's Sky RMS at most 1.1 x TPOINT's, at most TPOINT's
term count + 2 terms, and a leave-one-out RMS no worse than that of TPOINT's terms.
Writes benchmarks/results/fauto.json.

    .venv/bin/python benchmarks/fauto.py [--pairs FOLDER ...] [--azimuth S-E] [--order 8]
        [--product-order 8] [--start-rule popn|significance|never] [--no-exchanges] [--only STEM] [--out PATH]
"""

from __future__ import annotations

import argparse
import dataclasses
import inspect
import json
import math
import time
from pathlib import Path

import jax
import numpy as np

import pointax as px
from pointax.analysis.fauto_search import fauto
from pointax.terms.linear import NotYetInPointax

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
BUNDLED = [(REPO / "examples" / "data" / "mmt_20210821.dat", REPO / "examples" / "data" / "mmt_20210821.mod", "S-E")]


def find_pairs(folder: Path, azimuth: str) -> list[tuple[Path, Path, str]]:
    """``(run, model, azimuth)`` for every ``*.dat`` with a model file of the same stem."""
    out = []
    for dat in sorted(folder.glob("*.dat")):
        for ext in (".mod", ".MOD"):
            mod = dat.with_suffix(ext)
            if mod.exists():
                out.append((dat, mod, azimuth))
                break
    return out


def loo_rms(model: px.Model, obs) -> float:
    """Leave-one-out RMS (radians): star i's on-sky residual from a fit of the others
    (weight 0 on star i), over every star of weight > 0 in ``obs``."""
    used = np.asarray(obs.weight) > 0
    sq = []
    for i in np.flatnonzero(used):
        w = used.astype(float)
        w[i] = 0.0
        result = px.fit(model, obs, weights=w)
        r = np.asarray(px.residuals(result.model, obs))[i]
        sq.append(float(r @ r))
    return math.sqrt(sum(sq) / len(sq))


def masked_like_tpoint(model: px.Model, obs, n_masked: int) -> list[int]:
    """Rows (from 0) to leave out so that as many stars are fitted as TPOINT's model file
    says (its N): the model file does not say which, so the star with the largest
    on-sky residual under ``model`` fitted by pointax is left out, the fit repeated, and
    so on ``n_masked`` times (an inference; the rows are printed with the table)."""
    w = np.ones(len(obs.encoder))
    out = []
    for _ in range(max(n_masked, 0)):
        r = np.asarray(px.residuals(px.fit(model, obs, weights=w).model, obs))
        on_sky = np.where(w > 0, np.hypot(r[:, 0], r[:, 1]), -1.0)
        k = int(np.argmax(on_sky))
        w[k] = 0.0
        out.append(k)
    return out


def _shown(path: Path) -> str:
    """``path`` relative to the repository when inside it, else as given."""
    try:
        return str(Path(path).resolve().relative_to(REPO))
    except ValueError:
        return str(path)


def one_pair(dat: Path, mod: Path, azimuth: str, order: int | None, options: dict) -> dict:
    """FAUTO on the run and the comparison with TPOINT's model (figures in arcsec)."""
    arcsec = px.units.ARCSEC
    run = px.io.read_tpoint(dat, azimuth=azimuth)
    tp = px.io.read_model(mod)
    # TPOINT's FAUTO flags the terms it adds '&'; a model whose authors named it FAUTO's
    # output (``*fauto*.mod``) counts too, '&' or not (FAUTO may add no harmonic).
    is_fauto = any(t.parallel for t in tp.terms) or "fauto" in Path(mod).stem.lower()
    # TPOINT's terms as pointax fits them: the fitted ones ('=' terms held at 0 are left
    # out), those pointax cannot build named in the row and left out.
    fitted, unknown = [], []
    for t in tp.terms:
        if t.fixed and t.value == 0.0:
            continue
        try:
            px.terms.tpoint([t.name.upper()], **run.term_options())
        except NotYetInPointax:
            unknown.append(t.name)
            continue
        fitted.append(t)
    tp_model = run.model(px.terms.tpoint([t.name.upper() for t in fitted], **run.term_options()))
    tp_model = tp_model.set(**{t.name.upper(): t.value * arcsec for t in fitted if t.fixed})
    tp_model = tp_model.fix(*(t.name.upper() for t in fitted if t.fixed))
    # The stars TPOINT fitted: as many as its N (the others masked, see masked_like_tpoint).
    obs = run.observations
    masked = masked_like_tpoint(tp_model, obs, len(run) - (tp.n_obs or len(run)))
    weight = np.ones(len(run))
    weight[masked] = 0.0
    obs = px.Observations(obs.encoder, obs.target, weight, obs.convention, obs.readings)
    run = dataclasses.replace(run, observations=obs)
    t0 = time.perf_counter()
    built = fauto(run, **options) if order is None else fauto(run, max_order=order, **options)
    seconds = time.perf_counter() - t0
    tp_fit = px.fit(tp_model, obs)
    ours = run.model(built.model.terms)
    row = {
        "run": _shown(dat),
        "model": _shown(mod),
        "tpoint_fauto_model": is_fauto,
        "n_obs": len(run),
        "tpoint_n": tp.n_obs,
        "tpoint_terms": sum(1 for t in tp.terms if not t.fixed),
        "tpoint_terms_not_in_pointax": unknown,
        "tpoint_sky_rms": tp.sky_rms,
        "pointax_terms": len(built.names),
        "pointax_sky_rms": built.sky_rms / arcsec,
        "masked_rows": [k + 1 for k in masked],
        "n_fitted": int(np.sum(weight > 0)),
        "tpoint_terms_fitted_by_pointax_sky_rms": float(tp_fit.sky_rms) / arcsec,
        "pointax_loo_rms": loo_rms(ours, obs) / arcsec,
        "tpoint_terms_loo_rms": loo_rms(tp_model, obs) / arcsec,
        "pointax_added": list(built.added),
        "pointax_start_terms_dropped": [s.term for s in built.steps if s.action == "drop" and s.term not in built.added
                                        and s.term in built.steps[0].term.split()],
        "pointax_steps": [f"{s.stage} {s.action} {s.term}" for s in built.steps[1:]],
        "pointax_step_table": [s.to_dict() for s in built.steps],
        "tpoint_added": [t.name for t in tp.terms if t.parallel],
        "fauto_seconds": seconds,
    }
    if is_fauto and tp.sky_rms:
        row["targets"] = {
            "sky_rms_at_most_1.1x": row["pointax_sky_rms"] <= 1.1 * tp.sky_rms,
            "terms_at_most_tpoint_plus_2": row["pointax_terms"] <= row["tpoint_terms"] + 2,
            "loo_no_worse": row["pointax_loo_rms"] <= row["tpoint_terms_loo_rms"],
        }
    return row


def main() -> dict:
    jax.config.update("jax_enable_x64", True)  # the leave-one-out refits and residuals in float64
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", action="append", default=[], metavar="FOLDER", help="folder of RUN.dat + RUN.mod pairs")
    parser.add_argument("--azimuth", default="N-E", help="how the --pairs runs count azimuth (default N-E; MMT: S-E)")
    parser.add_argument("--order", type=int, default=None, help="FAUTO's highest harmonic order (default: fauto's)")
    parser.add_argument("--product-order", type=int, default=None,
                        help="FAUTO's highest product-harmonic order (default: fauto's)")
    parser.add_argument("--start-rule", default=None, help="FAUTO's start_rule (default: fauto's)")
    parser.add_argument("--collinearity", type=float, default=None, help="FAUTO's collinearity (default: fauto's)")
    parser.add_argument("--no-exchanges", action="store_true", help="FAUTO without its exchange steps (exchanges=False)")
    parser.add_argument("--only", action="append", default=[], metavar="STEM",
                        help="only the pairs whose run file name contains STEM (repeatable)")
    parser.add_argument("--no-bundled", action="store_true", help="leave out the repository's own runs")
    parser.add_argument("--out", default=str(HERE / "results" / "fauto.json"))
    args = parser.parse_args()

    pairs = [] if args.no_bundled else list(BUNDLED)
    for folder in args.pairs:
        pairs += find_pairs(Path(folder), args.azimuth)
    if args.only:
        pairs = [p for p in pairs if any(stem in p[0].name for stem in args.only)]
    options = {k: v for k, v in (("max_product_order", args.product_order), ("start_rule", args.start_rule),
                                 ("collinearity", args.collinearity)) if v is not None}
    if args.no_exchanges:
        options["exchanges"] = False
    rows = [one_pair(dat, mod, az, args.order, options) for dat, mod, az in pairs]
    head = (
        f"{'run':<28s} {'FAUTO?':>6s} {'N':>4s} {'N TP':>4s} {'M px':>5s} {'M TP':>5s} {'Sky px':>7s} {'Sky TP':>7s} "
        f"{'LOO px':>7s} {'LOO TP':>7s}  targets"
    )
    print(head)
    print("-" * len(head))
    for r in rows:
        t = r.get("targets")
        verdict = "n/a (not a FAUTO model)" if t is None else ("met" if all(t.values()) else "MISSED: " + ", ".join(
            k for k, ok in t.items() if not ok))
        print(
            f"{Path(r['run']).name[:28]:<28s} {'yes' if r['tpoint_fauto_model'] else 'no':>6s} {r['n_obs']:4d} {r['n_fitted']:4d} "
            f"{r['pointax_terms']:5d} {r['tpoint_terms']:5d} {r['pointax_sky_rms']:7.3f} "
            f"{(r['tpoint_sky_rms'] or float('nan')):7.3f} {r['pointax_loo_rms']:7.3f} {r['tpoint_terms_loo_rms']:7.3f}  {verdict}"
        )
    print("\nN: stars in the run; N TP: stars fitted, as many as TPOINT's model file says (rows left out: "
          + "; ".join(f"{Path(r['run']).name} {r['masked_rows']}" for r in rows if r["masked_rows"]) + ")")
    print("Sky RMS, LOO: arcsec; LOO TP: TPOINT's terms fitted by pointax, each star left out in turn"
          + "".join(f"; {Path(r['run']).name} without {', '.join(r['tpoint_terms_not_in_pointax'])} (not in pointax)"
                    for r in rows if r["tpoint_terms_not_in_pointax"]) + ".")
    defaults = inspect.signature(fauto).parameters
    order = args.order if args.order is not None else defaults["max_order"].default
    out = {"order": order,
           "product_order": options.get("max_product_order", defaults["max_product_order"].default),
           "start_rule": options.get("start_rule", defaults["start_rule"].default),
           "exchanges": options.get("exchanges", defaults["exchanges"].default), "runs": rows}
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    # Paths of --pairs runs outside the repository are kept as given (their source is the user's).
    Path(args.out).write_text(json.dumps(out, indent=2) + "\n")
    return out


if __name__ == "__main__":
    main()
