"""Optional packages: imported where a feature needs them, with a one-line error if missing."""

from __future__ import annotations

import importlib
from types import ModuleType

from .errors import MissingDependencyError

__all__ = ["require"]


def require(module: str, feature: str, packages: str, extra: str) -> ModuleType:
    """The module ``module``, or a :class:`~brokenness.errors.MissingDependencyError`:
    "``feature`` needs the optional ``packages``: pip install 'brokenness[``extra``]'"."""
    try:
        return importlib.import_module(module)
    except ImportError:
        raise MissingDependencyError(
            f"{feature} needs the optional {packages}: pip install 'brokenness[{extra}]'"
        ) from None
