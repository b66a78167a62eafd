"""``brokenness.register``: align one map with a reference."""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..errors import MapError
from ..grid import OccupancyMap
from ..limits import check_candidates
from ..transform import RigidTransform
from .base import Candidate, Registration
from .methods import make_registrar

__all__ = ["EXAMINED_HYPOTHESES", "as_map", "register"]

#: Hypotheses :func:`register` examines (refines and ranks) at least, however few it reports:
#: the search breadth of the measure (``BrokennessOptions.max_candidates``, 12). The best
#: hypothesis and the ranking do not depend on ``max_candidates`` up to this number.
EXAMINED_HYPOTHESES = 12


def _search_options(method: str, examined: int) -> dict[str, Any]:
    """Default options of ``method`` that let ``examined`` distinct hypotheses come out.

    For iFMI: ``min(examined, 64)`` rotation peaks (at least 2), every one of them (not only
    those half as high as the best), two translations each. The random walk needs none.
    """
    if method != "ifmi":
        return {}
    return {"rotation_peaks": min(max(2, examined), 64), "translation_peaks": 2, "peak_ratio": 0.0}


def as_map(value: OccupancyMap | ArrayLike, what: str = "map") -> OccupancyMap:
    """An :class:`OccupancyMap` from a map or a 2D array.

    Arrays are read by :meth:`OccupancyMap.from_array`, as every function of the package
    reads them: ``bool`` arrays are occupied (True) / free (False); integer arrays holding
    only -1, 0 and 1 are cell states (unknown / free / occupied, as
    :attr:`OccupancyMap.states`); other integer arrays and float arrays are
    ``nav_msgs/OccupancyGrid`` occupancy values.

    Raises
    ------
    MapError
        If the array is not a valid map (the message names ``what``).
    """
    if isinstance(value, OccupancyMap):
        return value
    try:
        return OccupancyMap.from_array(value)
    except MapError as exc:
        raise type(exc)(f"the {what}: {exc}") from None


def register(
    reference: OccupancyMap | ArrayLike,
    moving: OccupancyMap | ArrayLike,
    *,
    method: str = "ifmi",
    seed: int | None = None,
    max_candidates: int = 3,
    **options: Any,
) -> Registration:
    """Find the rigid transform that maps the cells of ``moving`` onto ``reference``.

    Parameters
    ----------
    reference, moving : OccupancyMap or array_like
        The two maps (arrays as in :func:`as_map`). Their shapes may differ, and ``moving``
        may show only a part of the reference. When both have a resolution and the two
        differ, ``moving`` is resampled to the reference's resolution before registering.
    method : {"ifmi", "random-walk"}
        Registration method, see :func:`brokenness.registration.make_registrar`.
    seed : int, optional
        Seed of the stochastic method (iFMI is deterministic and ignores it).
    max_candidates : int, default 3
        Number of hypotheses reported in :attr:`Registration.candidates` (fewer when the
        method finds no more distinct ones), at most
        :data:`~brokenness.limits.MAX_CANDIDATES`. It does not change the answer: the method is
        always asked for ``max(EXAMINED_HYPOTHESES, max_candidates)`` distinct hypotheses
        (:data:`EXAMINED_HYPOTHESES` = 12; for iFMI the most promising ones of its spectral
        search, each refined at full resolution), which it ranks by the cells of ``moving``
        that agree with reference walls under each (the random walk: by the cells each
        explains that better-ranked ones do not); the first ``max_candidates`` of that
        ranking are reported. The best hypothesis, its confidence and the order of the
        reported ones are thus the same for every ``max_candidates`` up to 12; asking for
        more examines that many, and a hypothesis beyond the twelfth may then rank first.
    **options
        Options of the method, e.g. ``n_angles`` or ``max_size`` of
        :class:`~brokenness.registration.IFMIRegistrar`. For iFMI three of them default to
        a search wide enough for the hypotheses examined, ``rotation_peaks = min(max(12,
        max_candidates), 64)``, ``translation_peaks = 2`` and ``peak_ratio = 0`` (every one
        of those rotation peaks, two translations each), not to the defaults of
        :class:`~brokenness.registration.IFMIRegistrar`; options given here replace them
        (a narrower search may yield fewer hypotheses). ``brokenness register`` uses the
        same defaults: the command line and this function give the same answer.

    Returns
    -------
    Registration
        ``.candidates`` are the first ``max_candidates`` of the ranking, best first;
        ``.transform`` (the best's) maps cells ``(x, y) = (column, row)`` of the *original*
        ``moving`` onto reference cells (with ``scale`` = moving resolution / reference resolution
        when they differ) and carries the world-frame transform when both maps have a
        resolution and an origin; ``.confidence`` in [0, 1].

    Raises
    ------
    MapError
        If a map is not 2D or has no occupied cell.
    ParameterError
        For an unknown method or invalid options.

    Examples
    --------
    >>> import numpy as np
    >>> ref = np.zeros((120, 160), dtype=bool)
    >>> ref[20, 10:150] = ref[100, 10:150] = ref[20:101, 10] = ref[20:60, 150] = True
    >>> ref[60, 110:151] = True
    >>> moving = np.roll(ref, (7, -5), axis=(0, 1))
    >>> reg = register(ref, moving)
    >>> [round(v) for v in reg.transform.translation], round(reg.rotation_deg)
    ([5, -7], 0)
    """
    max_candidates = check_candidates(max_candidates)  # in [1, MAX_CANDIDATES], before work
    ref_map = as_map(reference, "reference")
    mov_map = as_map(moving, "moving map")
    if ref_map.n_occupied == 0:
        raise MapError("the reference has no occupied cell, there is nothing to register to")
    if mov_map.n_occupied == 0:
        raise MapError("the moving map has no occupied cell, there is nothing to register")
    start = time.perf_counter()
    work = mov_map
    # original moving cells -> cells of the map that is registered (identity unless resampled)
    to_work = RigidTransform.identity()
    if (
        ref_map.resolution is not None
        and mov_map.resolution is not None
        and not np.isclose(ref_map.resolution, mov_map.resolution, rtol=1e-9, atol=0.0)
    ):
        from ..io.resample import resample_to_resolution

        work = resample_to_resolution(mov_map, ref_map.resolution)
        s = mov_map.resolution / ref_map.resolution
        # the centre of column x lands on (x + 0.5) * s - 0.5 of the resampled grid; rows
        # are anchored at the bottom (the origin is the lower-left corner), which adds
        # rows' - rows * s to y (see brokenness.io.resample)
        shift_y = work.shape[0] - mov_map.shape[0] * s
        to_work = RigidTransform(0.0, 0.5 * s - 0.5, 0.5 * s - 0.5 + shift_y, s)
        if work.n_occupied == 0:
            raise MapError("the moving map has no occupied cell left at the reference's resolution")
    # the search does not depend on how many hypotheses are reported: at least
    # EXAMINED_HYPOTHESES are examined and ranked, the first max_candidates kept
    examined = max(EXAMINED_HYPOTHESES, int(max_candidates))
    registrar = make_registrar(
        method, seed=seed, **{**_search_options(method, examined), **options}
    )
    prepared = registrar.prepare_reference(ref_map.states)
    found = registrar.candidates(prepared, work.states, examined)[: int(max_candidates)]
    if not found:  # pragma: no cover - the protocol promises at least one
        raise MapError(f"registration method {method!r} returned no hypothesis")
    candidates = tuple(
        Candidate(
            c.transform.compose(to_work).with_world(mov_map, ref_map), c.confidence, c.acceptance
        )
        for c in found
    )
    seconds = time.perf_counter() - start
    best = candidates[0]
    return Registration(
        transform=best.transform,
        confidence=best.confidence,
        candidates=candidates,
        method=registrar.name,
        seconds=seconds,
    )
