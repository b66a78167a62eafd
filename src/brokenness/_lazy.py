"""Public names of a package imported on first use (PEP 562 ``__getattr__``).

A package that re-exports the names of its heavy submodules (numpy, SciPy, OpenCV) makes
every import of any of its modules pay for all of them: ``brokenness batch`` would load the
whole pipeline in the batch process, which only reads a manifest and hands pairs to its
workers. :func:`lazy_exports` gives such a package a module ``__getattr__`` and
``__dir__`` that import a name's submodule when the name is first looked up, and keep the
value in the package, so that the next look-up is a plain attribute.

Usage, in a package's ``__init__.py`` (the ``TYPE_CHECKING`` block tells type checkers and
readers where each name comes from)::

    if TYPE_CHECKING:
        from .load import load_map

    __getattr__, __dir__ = lazy_exports(__name__, {"load_map": ".load"})
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["lazy_exports"]


def lazy_exports(
    package: str, names: Mapping[str, str], submodules: tuple[str, ...] = ()
) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """A module ``__getattr__`` and ``__dir__`` that import public names on first use.

    Parameters
    ----------
    package : str
        The package's ``__name__``.
    names : mapping
        Public name -> the module that defines it, relative to ``package`` (``".load"``).
    submodules : tuple of str
        Submodules that ``package.<name>`` imports on first use (as an eager
        ``__init__.py`` that imported them made them attributes of the package).

    Returns
    -------
    (getattr, dir)
        The package's ``__getattr__`` and ``__dir__``.
    """

    def __getattr__(name: str) -> Any:
        if name in names:
            value = getattr(importlib.import_module(names[name], package), name)
        elif name in submodules:
            value = importlib.import_module(f".{name}", package)
        else:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        setattr(sys.modules[package], name, value)  # the next look-up: a plain attribute
        return value

    def __dir__() -> list[str]:
        return sorted(set(vars(sys.modules[package])) | set(names) | set(submodules))

    return __getattr__, __dir__
