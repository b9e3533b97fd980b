"""Lazy package namespaces (PEP 562): names are imported from their modules on first use.

``import pointax`` then costs only what it imports itself, and astropy, torch, dask and
the solvers load when a function that needs them is first looked up.

    __getattr__, __dir__ = lazy_namespace(__name__, {"AltAz": "mount_models", ...}, ("io", "sky"))

A function may share its name with the module defining it (``pointax.command`` the
function, ``pointax/core/inverse.py`` the module). Eager imports bound the function last, and so does this:
when Python's import system stores the submodule on the package as an attribute of that
name, the package keeps the function instead.
"""

from __future__ import annotations

import importlib
import sys
import types
from collections.abc import Callable, Iterable, Mapping

__all__ = ["lazy_namespace"]


class LazyPackage(types.ModuleType):
    """A package whose exported functions are not replaced by same-named submodules."""

    def __setattr__(self, name: str, value) -> None:
        shadowed = self.__dict__.get("_lazy_shadowed", ())
        if name in shadowed and isinstance(value, types.ModuleType) and value.__name__ == f"{self.__name__}.{name}":
            # Python's import system binding pointax/core/inverse.py to pointax.command: keep the
            # function (looked up by __getattr__ on first use).
            return
        super().__setattr__(name, value)


def lazy_namespace(
    package: str, exports: Mapping[str, str], submodules: Iterable[str] = (), shadowed: Iterable[str] = ()
) -> tuple[Callable[[str], object], Callable[[], list[str]]]:
    """``__getattr__`` and ``__dir__`` for the package ``package``.

    Args:
        package: the package's ``__name__``.
        exports: public name -> the submodule (relative to the package, without a
            leading dot) that defines it.
        submodules: submodules exported as themselves: names, or a mapping of the
            exported name -> the submodule's path relative to the package (a room's
            module exported at the top, ``"rotations": "core.rotations"``).
        shadowed: more exported names that a submodule of the same name must not
            replace (those exported from a module of their own name always are).
    """
    module = sys.modules[package]
    exports = dict(exports)
    submodules = dict(submodules) if isinstance(submodules, Mapping) else {name: name for name in submodules}
    module.__dict__["_lazy_shadowed"] = frozenset(name for name, where in exports.items() if where == name) | set(shadowed)
    module.__class__ = LazyPackage

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
