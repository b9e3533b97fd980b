"""The package's rooms and who may import whom, read from the source (every import
statement, at module level or inside a function).

The rooms, lowest first: ``core`` (the pure-JAX forward model), ``terms`` (the term
library, model factories), ``fitting`` (every fit), ``sky`` (astropy: sun and stars),
``io`` (file formats), ``plots``, ``analysis``/``planning``/``procedures``/``sunsensor``
(work built on fits), ``cli`` (the command line). A lower room never imports a higher one.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "pointax"

# room -> the pointax rooms it may import (besides itself).
MAY_IMPORT = {
    "core": set(),
    "terms": {"core"},
    "fitting": {"core"},
    "sky": {"core"},
    "io": {"core", "terms", "fitting (public names only)"},
    "plots": {"core", "fitting (public names only)"},
    "planning": {"core", "terms", "fitting", "sky", "plots"},
    "analysis": {"core", "terms", "fitting", "io", "sky", "plots"},
    "procedures": {"core", "terms", "fitting", "io", "analysis", "plots"},
    "sunsensor": {"core", "terms", "io"},
    "cli": {"core", "terms", "fitting", "io", "analysis", "planning", "plots", "procedures", "sky", "sunsensor"},
}

# room -> third-party packages it must not import.
FORBIDDEN_LIBRARIES = {
    "core": {"astropy", "matplotlib", "torch", "kornia", "dask", "distributed", "scipy"},
    "terms": {"astropy", "matplotlib", "torch", "kornia", "dask", "distributed"},
    "fitting": {"astropy", "matplotlib", "torch", "kornia"},
    "io": {"matplotlib", "torch", "kornia"},
}

# Private modules of the dependencies: never imported anywhere.
PRIVATE_MODULES = ("jax._src", "jaxlib", "optimistix._", "equinox._", "lineax._", "scipy.linalg.cython_")


def _imports(path: Path, package: Path = PACKAGE) -> list[tuple[int, str]]:
    """(line, absolute module) of every import in ``path`` (a file of ``package``); for
    ``from X import a`` both ``X`` and ``X.a`` (a may be a module)."""
    parts = list(path.relative_to(package.parent).with_suffix("").parts)
    package_parts = parts[:-1]
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package_parts[: len(package_parts) - (node.level - 1)]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module
            found.append((node.lineno, module))
            found += [(node.lineno, f"{module}.{alias.name}") for alias in node.names if alias.name != "*"]
    return found


def _room(module: str) -> str | None:
    parts = module.split(".")
    return parts[1] if parts[0] == "pointax" and len(parts) > 1 else None


def _is_module(module: str, package: Path) -> bool:
    relative = Path(*module.split(".")[1:])
    return (package / relative).with_suffix(".py").exists() or (package / relative / "__init__.py").exists()


def _sources(package: Path = PACKAGE):
    return sorted(p for p in package.rglob("*.py") if "__pycache__" not in p.parts)


def _violations(room: str, package: Path = PACKAGE) -> list[str]:
    """Every import in ``room`` of ``package`` that breaks :data:`MAY_IMPORT` or
    :data:`FORBIDDEN_LIBRARIES`, as ``path:line imports module``."""
    allowed = MAY_IMPORT[room]
    public_only = {r.split()[0] for r in allowed if "public" in r}
    allowed = {r.split()[0] for r in allowed} | {room}
    bad = []
    for path in _sources(package):
        where = path.relative_to(package.parent)
        if _room(".".join(where.with_suffix("").parts)) != room:
            continue
        for line, module in _imports(path, package):
            target = _room(module)
            if target is None:
                if module.split(".")[0] in FORBIDDEN_LIBRARIES.get(room, ()):
                    bad.append(f"{where}:{line} imports {module}")
            elif target == "__version__" or module == "pointax":
                continue
            elif target not in allowed:
                bad.append(f"{where}:{line} imports {module}")
            elif target in public_only and target != room and module != f"pointax.{target}" and _is_module(module, package):
                # ``from pointax.fitting import FitResult``: the room's public names only.
                bad.append(f"{where}:{line} imports {module} (only pointax.{target}'s public names)")
    return bad


def test_the_package_root_holds_only_init_and_main():
    assert sorted(p.name for p in PACKAGE.glob("*.py")) == ["__init__.py", "__main__.py"]


@pytest.mark.parametrize("room", sorted(MAY_IMPORT))
def test_a_room_imports_only_lower_rooms(room):
    bad = _violations(room)
    assert not bad, "\n".join(bad)


def test_no_private_module_of_a_dependency_is_imported():
    bad = [
        f"{path.relative_to(PACKAGE.parent)}:{line} imports {module}"
        for path in _sources()
        for line, module in _imports(path)
        if module.startswith(PRIVATE_MODULES)
    ]
    assert not bad, "\n".join(bad)


def test_the_rules_catch_a_lower_room_importing_a_higher_one(tmp_path):
    """The checker itself, on a made-up package: a core module importing io and astropy,
    and a plots module importing a fitting internal, are found; public names pass."""
    package = tmp_path / "pointax"
    for room in ("core", "io", "plots", "fitting"):
        (package / room).mkdir(parents=True)
        (package / room / "__init__.py").write_text("")
    (package / "fitting" / "batch.py").write_text("")
    (package / "core" / "probe.py").write_text("import numpy\nfrom ..io import read_tpoint\n\ndef f():\n    import astropy.units\n")
    (package / "plots" / "probe.py").write_text("from ..fitting import FitResult\nfrom ..fitting.batch import site_statuses\n")
    assert _violations("core", package) == [
        "pointax/core/probe.py:2 imports pointax.io",
        "pointax/core/probe.py:2 imports pointax.io.read_tpoint",
        "pointax/core/probe.py:5 imports astropy.units",
    ]
    assert _violations("plots", package) == [
        "pointax/plots/probe.py:2 imports pointax.fitting.batch (only pointax.fitting's public names)"
    ]
