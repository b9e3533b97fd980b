"""The examples run and do what they say."""

from __future__ import annotations

import importlib.util
import sys

from conftest import EXAMPLES


def test_new_error_term_recovers_the_wobble_within_one_sigma():
    spec = importlib.util.spec_from_file_location("new_error_term_example", EXAMPLES / "new_error_term.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    out = module.main(seed=0, verbose=False)
    assert out["converged"]
    assert abs(out["amp"] - 6.0) <= out["sigma"], out
    assert abs(out["phase"] - 35.0) < 5.0, out


def test_term_definition_is_at_most_20_lines():
    text = (EXAMPLES / "new_error_term.py").read_text().splitlines()
    start = next(i for i, line in enumerate(text) if line.startswith("class AzWobble"))
    end = next(i for i in range(start + 1, len(text)) if text[i] and not text[i].startswith(" "))
    body = [line for line in text[start:end] if line.strip()]
    assert len(body) <= 20, len(body)
