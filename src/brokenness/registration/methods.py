"""The registration methods by name, as ``compute_brokenness(method=...)`` selects them."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from ..errors import ParameterError

if TYPE_CHECKING:
    from .base import Registrar

__all__ = ["METHODS", "make_registrar"]

#: Names accepted by :func:`make_registrar` (and ``--method`` on the command line).
METHODS: tuple[str, ...] = ("ifmi", "random-walk")


def make_registrar(method: str = "ifmi", *, seed: int | None = None, **options: Any) -> Registrar:
    """A registration method, ready to drive.

    Parameters
    ----------
    method : {"ifmi", "random-walk"}
        ``"ifmi"``: improved Fourier-Mellin registration (deterministic, the default).
        ``"random-walk"``: the stochastic map-merging baseline of Birk & Carpin (2006).
    seed : int, optional
        Seed of the random walk (ignored by iFMI, which uses no randomness).
    **options
        Passed to the method's constructor.

    Raises
    ------
    ParameterError
        For an unknown method name or invalid options.
    """
    if method == "ifmi":
        from .ifmi import IFMIRegistrar

        return IFMIRegistrar(**options)
    if method == "random-walk":
        from .random_walk import RandomWalkRegistrar

        return RandomWalkRegistrar(seed=seed, **options)
    raise ParameterError(
        f"unknown registration method {method!r}; choose one of {', '.join(METHODS)}"
    )
