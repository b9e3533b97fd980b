"""An independent NumPy reference for TPOINT alt-az runs: the file's records, TPOINT's
linear terms (DESIGN.md's basis functions), its linear least squares, the rigorous
(sky-form) residuals and one Gauss-Newton step on them, and TPOINT's statistics.

Nothing here imports pointax. Angles are radians; A, E are azimuth and elevation as the
file counts them (the MMT files: from South through East)."""

from __future__ import annotations

import numpy as np

ARCSEC = np.pi / 180 / 3600


def read_run(path):
    """``(observed, raw, lines)``: ``(n, 2)`` observed and raw (A, E) radians and the
    ``(n,)`` file line of each record, by a plain reading of the file."""
    observed, raw, lines = [], [], []
    seen_caption = seen_params = False
    for number, text in enumerate(open(path, encoding="utf-8").read().splitlines(), 1):
        body = text.split("!", 1)[0].strip()
        if not body:
            continue
        if not seen_caption:
            seen_caption = True
            continue
        if body.startswith(":"):
            continue
        if body.upper() == "END":
            break
        if not seen_params:
            seen_params = True
            continue
        v = [float(x) for x in body.split()[:4]]
        observed.append(v[:2])
        raw.append(v[2:])
        lines.append(number)
    return np.radians(observed), np.radians(raw), np.asarray(lines)


def basis(name, A, E):
    """``(fA, fE)``: observed minus raw in A and E per unit coefficient (DESIGN.md;
    harmonics: A' = 180 deg - A, -f for A and S terms, +f for E terms)."""
    zero = np.zeros_like(A)
    table = {
        "IA": (-np.ones_like(A), zero),
        "IE": (zero, np.ones_like(A)),
        "CA": (-1 / np.cos(E), zero),
        "NPAE": (-np.tan(E), zero),
        "AN": (-np.sin(A) * np.tan(E), -np.cos(A)),
        "AW": (-np.cos(A) * np.tan(E), np.sin(A)),
        "TF": (zero, -np.cos(E)),
        "TX": (zero, -1 / np.tan(E)),
        "HESA": (zero, np.sin(np.pi - A)),
        "HECA": (zero, np.cos(np.pi - A)),
    }
    return table[name]


def offsets(names, coefs, A, E):
    """``(dA, dE)`` of the model with ``coefs`` (radians) at (A, E)."""
    dA, dE = np.zeros_like(A), np.zeros_like(E)
    for name, c in zip(names, coefs):
        fA, fE = basis(name, A, E)
        dA, dE = dA + c * fA, dE + c * fE
    return dA, dE


def wrap(x):
    return (x + np.pi) % (2 * np.pi) - np.pi


def tpoint_residuals(names, coefs, observed, raw):
    """TPOINT's residuals ``(n, 2)``: (dA cos E, dE), terms at the observed position."""
    A, E = observed[:, 0], observed[:, 1]
    dA, dE = offsets(names, coefs, A, E)
    return np.stack([wrap(A - raw[:, 0] - dA) * np.cos(E), E - raw[:, 1] - dE], axis=-1)


def lstsq(names, observed, raw, used, fixed=None):
    """TPOINT's linear least squares over the ``used`` rows: coefficients (radians) of
    ``names``, with the terms of ``fixed`` ({name: value}) held at their values."""
    A, E = observed[:, 0], observed[:, 1]
    cols = []
    for name in names:
        fA, fE = basis(name, A, E)
        cols.append(np.concatenate([fA * np.cos(E), fE]))
    X = np.stack(cols, axis=-1)
    y = np.concatenate([wrap(A - raw[:, 0]) * np.cos(E), E - raw[:, 1]])
    for name, value in (fixed or {}).items():
        fA, fE = basis(name, A, E)
        y = y - value * np.concatenate([fA * np.cos(E), fE])
    rows = np.concatenate([used, used])
    return np.linalg.lstsq(X[rows], y[rows], rcond=None)[0]


def _direction(A, E):
    return np.stack([np.sin(A) * np.cos(E), np.cos(A) * np.cos(E), np.sin(E)], axis=-1)


def sky_residuals(names, coefs, observed, raw, iterations=10):
    """The rigorous residuals ``(n, 2)``: the model's position P solves
    P = raw + offsets(P); the residual is minus the gnomonic offset of P's direction
    from the observed one, in the observed direction's tangent plane (along
    increasing A, along increasing E)."""
    Ap, Ep = raw[:, 0].copy(), raw[:, 1].copy()
    for _ in range(iterations):
        dA, dE = offsets(names, coefs, Ap, Ep)
        Ap, Ep = raw[:, 0] + dA, raw[:, 1] + dE
    p = _direction(Ap, Ep)
    A, E = observed[:, 0], observed[:, 1]
    t = _direction(A, E)
    e_a = np.stack([np.cos(A), -np.sin(A), np.zeros_like(A)], axis=-1)
    e_e = np.stack([-np.sin(E) * np.sin(A), -np.sin(E) * np.cos(A), np.cos(E)], axis=-1)
    depth = np.sum(p * t, axis=-1)
    return -np.stack([np.sum(p * e_a, axis=-1), np.sum(p * e_e, axis=-1)], axis=-1) / depth[:, None]


def statistics(r, used, jac_used, n_params):
    """TPOINT's Sky RMS, Popn SD and sigmas (radians) from residuals ``r`` (n, 2) and the
    Jacobian of the used rows' residuals."""
    n = int(used.sum())
    rms = np.sqrt(np.sum(r[used] ** 2) / n)
    popn = rms * np.sqrt(n / (n - n_params))
    sigmas = rms * np.sqrt(np.diag(np.linalg.inv(jac_used.T @ jac_used)))
    return rms, popn, sigmas


def gauss_newton_step(names, coefs, observed, raw, used, residuals=sky_residuals, h=1e-7):
    """One linearised adjustment of every coefficient from ``coefs`` over the ``used``
    rows, Jacobian by central differences. Returns ``(new coefs, rms, popn, sigmas)``
    with the statistics of TPOINT (residuals after the step, Jacobian at the start)."""
    coefs = np.asarray(coefs, np.float64)

    def r(c):
        return residuals(names, c, observed, raw)[used].reshape(-1)

    J = np.stack([(r(coefs + h * e) - r(coefs - h * e)) / (2 * h) for e in np.eye(len(coefs))], axis=-1)
    new = coefs - np.linalg.lstsq(J, r(coefs), rcond=None)[0]
    after = residuals(names, new, observed, raw)
    rms, popn, sigmas = statistics(after, used, J, len(coefs))
    return new, rms, popn, sigmas


def read_model_values(path):
    """``({name: value arcsec}, {name: sigma arcsec}, n, sky_rms)`` of a TPOINT model
    file, plainly read."""
    lines = [x for x in open(path, encoding="utf-8").read().splitlines() if x.strip() and not x.startswith("!")]
    head = lines[1].split()
    values, sigmas = {}, {}
    for text in lines[2:]:
        if text.strip() == "END":
            break
        tokens = text.replace("&", " ").replace("=", " ").split()
        values[tokens[0]] = float(tokens[1])
        if len(tokens) > 2:
            sigmas[tokens[0]] = float(tokens[2])
    return values, sigmas, int(head[1]), float(head[2])
