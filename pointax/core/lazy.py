"""Lazy package namespaces (PEP 562): names are imported from their modules on first use.

``import pointax`` then costs only what it imports itself, and astropy, torch, dask and
the solvers load when a function that needs them is first looked up.

    __getattr__, __dir__ = lazy_namespace(__name__, {"AltAz": "terms.model_factories", ...}, ("io", "sky"))

No exported name is also the name of a submodule of the same package: Python's import
system binds a submodule to its package's attribute of that name when the submodule is
imported, which would replace an exported function by the module defining it
(:func:`lazy_namespace` refuses such a pair).
"""

from __future__ import annotations

import importlib
import os
import sys
from collections.abc import Callable, Iterable, Mapping

__all__ = ["lazy_namespace"]


def lazy_namespace(
    package: str, exports: Mapping[str, str], submodules: Iterable[str] | Mapping[str, str] = ()
) -> tuple[Callable[[str], object], Callable[[], list[str]]]:
    """``__getattr__`` and ``__dir__`` for the package ``package``.

    Args:
        package: the package's ``__name__``.
        exports: public name -> the submodule (relative to the package, without a
            leading dot) that defines it.
        submodules: submodules exported as themselves: names, or a mapping of the
            exported name -> the submodule's path relative to the package (a room's
            module exported at the top, ``"rotations": "core.rotations"``).

    Raises:
        ValueError: an exported name is also the name of one of the package's
            submodules (the import system would replace it by the module).
    """
    module = sys.modules[package]
    exports = dict(exports)
    submodules = dict(submodules) if isinstance(submodules, Mapping) else {name: name for name in submodules}
    own = _submodule_names(module)
    clashes = {name for name in exports if name in own}
    clashes |= {name for name, path in submodules.items() if name in own and path != name}
    if clashes:
        names = ", ".join(sorted(clashes))
        raise ValueError(f"{package}: the exported {names} would be replaced by the submodule of that name")

    def __getattr__(name: str):
        if name in exports:
            value = getattr(importlib.import_module(f".{exports[name]}", package), name)
        elif name in submodules:
            value = importlib.import_module(f".{submodules[name]}", package)
        else:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        module.__dict__[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted(set(module.__dict__) | set(exports) | set(submodules))

    return __getattr__, __dir__


def _submodule_names(module) -> set[str]:
    """The names of the package's own submodules (its ``.py`` files and folders)."""
    names = set()
    for folder in getattr(module, "__path__", ()):
        with os.scandir(folder) as entries:
            for entry in entries:
                if entry.name.endswith(".py"):
                    names.add(entry.name[:-3])
                elif entry.is_dir() and entry.name.isidentifier():
                    names.add(entry.name)
    return names
