"""Registration: the rigid transform that aligns a map (or a part of it) with a reference.

- :func:`register` -- one map against a reference, the public entry point;
- :class:`IFMIRegistrar` -- improved Fourier-Mellin registration (deterministic, default);
- :func:`make_registrar` -- a method by name, as the recursion of Algorithm 1 drives it;
- :class:`Registration`, :class:`Candidate`, :class:`Registrar` -- results and interface;
- :mod:`~brokenness.registration.orientation` -- rotation hypotheses from the directions of
  a set of cells' walls (Hough spectra), which the measure's recovery places at every
  translation when the spectral registration of those cells finds nothing.

Only :data:`METHODS` and :func:`make_registrar` are loaded with the package; the other
names (numpy, OpenCV, SciPy's FFT) on first use (:mod:`brokenness._lazy`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_exports
from .methods import METHODS, make_registrar

if TYPE_CHECKING:
    from .api import register
    from .base import Candidate, Registrar, Registration
    from .ifmi import IFMIRegistrar

__all__ = [
    "METHODS",
    "Candidate",
    "IFMIRegistrar",
    "Registrar",
    "Registration",
    "make_registrar",
    "register",
]

__getattr__, __dir__ = lazy_exports(
    __name__,
    {
        "register": ".api",
        "Candidate": ".base",
        "Registrar": ".base",
        "Registration": ".base",
        "IFMIRegistrar": ".ifmi",
    },
)
