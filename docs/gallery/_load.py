"""Load an example of ``examples/`` as a module (the gallery scripts run its ``main``)."""

import importlib.util
import os
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
QUICK = os.environ.get("POINTAX_DOCS_QUICK", "0") == "1"


def example(name: str):
    path = REPO / "examples" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(f"example_{name}", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module
