"""The batched fit's fast pass (pointax.fitting.batch_fast_pass) on the solo fit's problem:
its answer equals the solo fit's (px.fit, optimistix's Levenberg-Marquardt and an SVD)
site by site; one construction of the site data serves one site and a chunk; and no
module of the package reads optimistix's private solver state."""

from __future__ import annotations

import ast
from pathlib import Path

import jax
import numpy as np
import pytest

import pointax as px
from pointax.core.simulate import encoder_grid
from pointax.fitting import batch_fast_pass as fast_pass
from pointax.fitting.problem import is_affine, site_data

PACKAGE = Path(px.__file__).resolve().parent


def _run(form, terms_form=px.terms.DEFAULT_FORM):
    truth = px.AltAz(px.terms.tpoint("IA IE CA AN AW", form=terms_form), residual_form=form).set(
        IA=px.arcsec(90), IE=px.arcsec(-25), CA=px.arcsec(14), AN=px.arcsec(6), AW=px.arcsec(-9)
    )
    sites = [px.simulate(truth, encoder_grid(6, (20, 40, 60, 80)), noise=px.arcsec(1.0), seed=k) for k in range(4)]
    return truth.with_values(np.zeros(len(truth.parameters))), sites


@pytest.mark.parametrize("terms_form", ["linear", "rigorous"])
@pytest.mark.parametrize("form", ["sky", "tpoint"])
def test_the_fast_pass_equals_the_solo_fit(form, terms_form):
    """The steps :func:`pointax.fit_batch` gives each model: TPOINT's linear terms are
    affine in the TPOINT form (one step) and start from it in the sky form; the rigorous
    terms (the default form) take the fixed steps of models not affine in their parameters."""
    start, sites = _run(form, terms_form)
    batch = px.stack_observations(sites)
    values = np.zeros((len(sites), len(start.free_parameters)))
    if terms_form == "rigorous":
        assert not is_affine(start) and not fast_pass.starts_in_tpoint_form(start)
        steps = fast_pass.DEFAULT_STEPS
    else:
        assert is_affine(start) == (form == "tpoint") and fast_pass.starts_in_tpoint_form(start) == (form == "sky")
        steps = 1 if form == "tpoint" else fast_pass.TPOINT_START_STEPS
    with jax.enable_x64(True):
        result, suspect = fast_pass.fast_pass(start, values, batch, steps, 1e-10, 1e-13)
    assert np.all(np.asarray(result.converged)) and not np.any(np.asarray(suspect))
    for k, obs in enumerate(sites):
        solo = px.fit(start, obs)
        np.testing.assert_allclose(np.asarray(result.values[k]), np.asarray(solo.values), rtol=0, atol=1e-12)
        np.testing.assert_allclose(np.asarray(result.sigmas[k]), np.asarray(solo.sigmas), rtol=1e-6)
        np.testing.assert_allclose(float(result.sky_rms[k]), float(solo.sky_rms), rtol=1e-9)


@pytest.mark.parametrize("form", ["sky", "tpoint"])
def test_one_construction_of_the_site_data_for_a_site_and_a_chunk(form):
    start, sites = _run(form)
    batch = px.stack_observations(sites)
    with jax.enable_x64(True):
        chunk = site_data(start, batch)
        for k, obs in enumerate(sites):
            one = site_data(start, obs)
            for a, b in zip(jax.tree.leaves(one), jax.tree.leaves(chunk)):
                np.testing.assert_allclose(np.asarray(a), np.asarray(b)[k, : np.shape(a)[0]], rtol=1e-15, atol=1e-15)


_PRIVATE_STATE = {"descent_state", "y_eval", "f_info", "search_state", "num_accepted_steps", "_GaussNewtonState"}


def test_no_module_reads_private_optimistix_state():
    """No attribute of optimistix's solver states (they are private: the public outputs
    are a solver's ``y``, ``aux`` and a ``Solution``), no private optimistix or lineax
    module or name. Docstrings do not count."""
    bad = []
    for path in sorted(PACKAGE.rglob("*.py")):
        tree = ast.parse(path.read_text(), str(path))
        where = path.relative_to(PACKAGE.parent)
        for node in ast.walk(tree):
            if isinstance(node, ast.Attribute) and node.attr in _PRIVATE_STATE:
                bad.append(f"{where}:{node.lineno} reads .{node.attr}")
            elif isinstance(node, ast.Name) and node.id.startswith("_") and node.id in _PRIVATE_STATE:
                bad.append(f"{where}:{node.lineno} names {node.id}")
            elif (
                isinstance(node, ast.Attribute)
                and node.attr.startswith("_")
                and isinstance(node.value, ast.Name)
                and node.value.id in {"optx", "optimistix", "lx", "lineax"}
            ):
                bad.append(f"{where}:{node.lineno} reads {node.value.id}.{node.attr}")
            elif isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] in {"optimistix", "lineax"}:
                if any(part.startswith("_") for part in node.module.split(".")) or any(
                    a.name.startswith("_") for a in node.names
                ):
                    bad.append(f"{where}:{node.lineno} imports from {node.module}")
    assert not bad, "\n".join(bad)
