"""Registration: the rigid transform that aligns a map (or a part of it) with a reference.

- :func:`register` -- one map against a reference, the public entry point;
- :class:`IFMIRegistrar` -- improved Fourier-Mellin registration (deterministic, default);
- :func:`make_registrar` -- a method by name, as the recursion of Algorithm 1 drives it;
- :class:`Registration`, :class:`Candidate`, :class:`Registrar` -- results and interface.
"""

from .api import register
from .base import Candidate, Registrar, Registration
from .ifmi import IFMIRegistrar
from .methods import METHODS, make_registrar

__all__ = [
    "METHODS",
    "Candidate",
    "IFMIRegistrar",
    "Registrar",
    "Registration",
    "make_registrar",
    "register",
]
