"""The paper's baseline registration: Birk & Carpin's map merging by adaptive random walk.

Birk (ICRA 2010) compares the spectral registration with the map-merging method of Birk &
Carpin (2006), called BCMM in the paper's tables: a stochastic search over rigid transforms
``(theta, tx, ty)`` that minimises the dissimilarity

.. math::

    \\Delta(T) = \\Psi(T(m), r) + c_{lock} \\, (\\mathrm{dis}(T(m), r) - \\mathrm{agr}(T(m), r))

where ``Psi`` is the picture distance (Manhattan distances to the nearest cell of the same
kind, both ways; see :func:`brokenness.picture_distance`), ``agr`` counts the cells known in
both maps that hold the same state and ``dis`` those that hold different states (occupied vs
free). The *acceptance indicator* ``omega = agr / (agr + dis)`` judges the result; it is
reported with every candidate (:attr:`Candidate.acceptance`) and, for ``compute_brokenness``
with this method, per partition (:func:`partition_acceptance`).

Every parameter and where it comes from
---------------------------------------
All options are fields of the frozen :class:`WalkOptions` (the registrar also takes them as
keywords). "Paper" means Birk & Carpin (2006) [1]_ / Carpin & Pillonetto (2005) [2]_ as
summarised by Birk (2010); "ours" means chosen by us and measured on the maps of
``tests/data`` and the paper-style tables (``benchmarks/experiment_tables.py``), because the
numerical settings of the original implementation were not available to us.

- ``Delta``, ``agr``, ``dis``, ``omega``, ``c_lock`` and ``Psi`` (sum over occupied and free
  cells, both directions, of the mean Manhattan distance to the nearest cell of the same
  kind): paper. ``Psi`` is restricted to the overlap (cells whose counterpart under ``T`` is
  known), because in the recursion of Algorithm 1 the moving map is often only a part of the
  reference; the lock term rewards a large overlap (ours).
- The distance maps: the paper's two-pass (forward / backward raster scan) Manhattan
  distance transform; we use OpenCV's two-pass ``distanceTransform`` with the 3x3 L1 mask,
  which computes the same exact Manhattan distances (tested against brute force, including
  cells that only the backward pass reaches, in ``tests/test_random_walk.py``). Distances
  are integers, stored as uint16: no division anywhere.
- ``lock_weight`` = 10 (ours): ``c_lock = lock_weight / N`` (``N`` known moving cells), so a
  perfect full overlap is worth ``lock_weight`` cells of picture distance whatever the map
  size; ``c_lock`` sets the weight directly.
- The search (paper, [2]_): Gaussian increments in ``(theta, ux, uy)`` whose covariance is
  estimated from the last ``window`` = 8 (ours) accepted increments (their second moment:
  the step size follows the steps that paid off) plus a floor ``min_rotation_step_deg`` =
  0.1, ``min_translation_step`` = 0.3 cell (ours: the walk never freezes); the mean is the
  average move of the last ``window`` steps, a rejected proposal counting as 0 (ours: a
  mean of accepted increments only kept pushing the walk out of an optimum). Before two
  steps were accepted the standard deviations are ``rotation_step_deg`` = 4 and
  ``translation_step`` = 2 % of the reference's larger side (ours). An improving step is
  always accepted, a worse one with the small fixed probability ``worse_acceptance`` = 0.05
  (paper: a small constant; the value is ours). Rotation turns about the moving map's
  centroid, so that the three coordinates are decoupled (ours).
- Restarts (paper: the walk restarts from good states when it stalls): a walker that has
  not improved its best Delta by more than ``tolerance`` = 0.01 in ``patience`` = 60 steps
  (ours) restarts from its best state with the initial step distribution (large steps
  again, to leave the basin if a better one is near), at most ``restarts`` = 2 times (ours);
  then it stops. The best state of each walker is kept.
- Multiple starts (ours; the paper starts one walk near the identity, which works for two
  maps of one robot but not for the remainder of a broken map, which has several good
  alignments, one per partition): ``rotations`` = 12 start angles, evenly spread, and per
  angle the ``walkers_per_angle`` = 2 best (lowest Delta) of a few start positions of the
  moving map's centroid (the reference's centroid, its own position, a ``start_grid`` = 6
  by 6 lattice over the reference's known cells); plus ``spectral_starts`` = 6 start poses
  from the spectral registration (iFMI hypotheses of the same remainder), which point at
  the partitions' own alignments. The walkers' states are the candidates: several
  distinct ones (``dedupe_cells`` = 8: results that move every corner of the box of the
  moving map's occupied cells by less are one) are returned, and the recursion keeps the
  one under which most cells agree. Each walker offers two states: its lowest Delta and
  the one that *explained* the most occupied cells on its way (within ``explain_cells``
  = 2 of a reference wall, the masking's ``c``), and the candidates are ranked greedily by
  the cells they explain that those ranked before them do not, ties by Delta (ours: on a
  remainder, whose reference walls other partitions also claim, we measured Delta lowest
  at a wrong placement of a part while the walk had passed through the right one; and
  near variants of the best alignment explain little that it does not).
  ``spectral_starts=0`` gives the pure stochastic search.
- Budgets: ``max_iterations`` = 300 steps per walker (ours; the iteration budget, counted in
  lockstep steps of all walkers: deterministic) and ``time_budget`` (seconds per
  registration, default none). A time budget makes the result depend on the machine and
  its load; only the iteration budget is deterministic, so it is the default.
- The budget of a search (ours): :func:`brokenness.compute_brokenness` falls back on a
  wider walk (:meth:`RandomWalkRegistrar.wider`, twice the start poses) when a step falls
  short, on wider walks of 13 regions of a remainder that no part dominates, and on wider
  walks of the suspect cells in each round of the recovery. On a map of the reference's place
  these run a few times; on a map of another place *every* step falls short, so they ran in
  every step (up to 15 wider walks, about 30 plain walks' worth, a step), and one control of
  the quick set took 627 s. So all the walks of one call -- the wider registrar's and the
  plain one's, which the measure makes before any walk -- are counted in one budget,
  ``search_budget`` = 24 plain walks' worth of evaluations of Delta
  (:attr:`WalkOptions.nominal_evaluations`: the start poses plus ``max_iterations + 1``
  evaluations of every walker). Only the wider walks are held to it: the one that spends it
  stops there (a count, deterministic like the iteration budget) and the measure asks a spent
  registrar for no more (its :attr:`~RandomWalkRegistrar.exhausted`); the plain walks of
  Algorithm 1 itself (one per step and reference, bounded by ``max_partitions``) always run,
  as iFMI's registrations do. A call's walks thus cost at most ``max(24, its plain walks)``
  plain walks, plus one step. Why 24 (measured on the realistic benchmark's degrees 0-5,
  84 maps, without the budget): a median of 6.3 plain walks' worth a call, 18.4-22.3 for the
  heaviest of degrees 4 and 5 (8-10 of it in plain walks), 34.3 for one (intel degree 5, 19.4
  in region walks; it is cut, and comes out 4 instead of 5); on the maps of other places the
  plain walks alone are 9-19. A budget of 8 for the wider walks alone cut csail degree 5's
  recovery short (4 instead of 5). See ``docs/benchmark-history.md``, issue 13, for what it
  changed.
- Subsampling (ours): when a map has more than ``max_points`` = 6000 occupied (or free)
  cells, an evenly spaced subset of them (row-major order, independent of the seed) takes
  part in the walk, and ``agr``/``dis`` are scaled back to cells; the final ranking of the
  walkers' best states uses every cell.

Repeatability: ``seed`` (default :data:`DEFAULT_SEED`) seeds a fresh
``numpy.random.default_rng`` stream inside every :meth:`RandomWalkRegistrar.candidates`
call; no global random state is used, so the same input gives the same output bit for bit,
alone, in a batch, in any order (unless a ``time_budget`` cuts a walk short).

Known limitations (of the method, not the implementation): when the moving map holds
several partitions, ``Psi`` averages over all of them, so the minimum of Delta can sit a
fraction of a degree away from the best transform of the largest partition (the recursion
refines the chosen candidate on the cells anyway), or at a wrong placement of a part (hence
the ranking by explained cells). A small part whose angle neither the coarse grid's best
start positions nor the spectral hypotheses come near can be missed (with
``walkers_per_angle=1`` the 120-degree part of the fifth map of the paper-style Table I was;
2 finds it, and took the realistic benchmark's quick set from 16 to 18 of 25 exact).

Cost of one evaluation: the distance maps of the reference are computed once by
:meth:`RandomWalkRegistrar.prepare_reference`, those of the moving map once per
:meth:`RandomWalkRegistrar.candidates` call; an evaluation transforms only the coordinates of
the sampled occupied and free cells of both maps and looks distances up, all walkers of a
step at once (``O(walkers x max_points)`` per step, independent of the map's size once the
maps have more than ``max_points`` cells of a kind).

References
----------
.. [1] A. Birk and S. Carpin, "Merging occupancy grid maps from multiple robots",
   Proceedings of the IEEE 94(7):1384-1397, 2006.
.. [2] S. Carpin and G. Pillonetto, "Motion planning using adaptive random walks",
   IEEE Transactions on Robotics 21(1):129-136, 2005.
.. [3] S. Carpin, A. Birk, V. Jucikas, "On map merging", Robotics and Autonomous Systems
   53(1):1-14, 2005.
.. [4] A. Birk, "A quantitative assessment of structural errors in grid maps", Autonomous
   Robots 28(2):187-196, 2010.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, fields, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import MapError, ParameterError
from ..grid import OccupancyMap
from ..transform import RigidTransform
from ._rw_scoring import MapTables, build_tables, explained_cells, score, subsample_tables
from .base import Candidate

__all__ = [
    "DEFAULT_SEED",
    "Dissimilarity",
    "RandomWalkRegistrar",
    "WalkOptions",
    "WalkProgress",
    "delta",
    "partition_acceptance",
]

#: Seed used when ``seed=None``: the random walk is always repeatable.
DEFAULT_SEED: int = 2006


# --------------------------------------------------------------------------------------------
# Input checks
# --------------------------------------------------------------------------------------------
def _states(states: Any, what: str) -> NDArray[np.int8]:
    """Validate a cell-state array (or take an OccupancyMap's) and return it as int8."""
    if isinstance(states, OccupancyMap):
        return states.states
    a = np.asarray(states)
    if a.ndim != 2 or a.shape[0] == 0 or a.shape[1] == 0:
        raise MapError(f"the {what} map must be a non-empty 2D grid, got shape {a.shape}")
    if not np.issubdtype(a.dtype, np.integer):
        raise MapError(f"the {what} map must hold integer cell states, got dtype {a.dtype}")
    if a.size and (a.min() < -1 or a.max() > 1):
        raise MapError(
            f"the {what} map holds states other than -1 (unknown), 0 (free), 1 (occupied)"
        )
    return a.astype(np.int8, copy=False)


# --------------------------------------------------------------------------------------------
# Public dissimilarity
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Dissimilarity:
    """Birk & Carpin's dissimilarity of a transformed map against a reference.

    Attributes
    ----------
    value : float
        ``Delta = psi + c_lock * (disagree - agree)``; lower is better.
    psi : float
        Picture distance restricted to the overlap, in cells.
    agree, disagree : float
        Cells known in both maps with equal / different states (occupied vs free).
    acceptance : float
        Acceptance indicator ``agree / (agree + disagree)`` in [0, 1] (0 without overlap).
    c_lock : float
        The weight of the agreement term that was used.
    """

    value: float
    psi: float
    agree: float
    disagree: float
    acceptance: float
    c_lock: float


def delta(
    reference: ArrayLike | OccupancyMap,
    moving: ArrayLike | OccupancyMap,
    transform: RigidTransform,
    *,
    c_lock: float | None = None,
    lock_weight: float = 10.0,
) -> Dissimilarity:
    """Dissimilarity Delta of Birk & Carpin (2006) of ``transform(moving)`` against ``reference``.

    Parameters
    ----------
    reference, moving : array_like of int8 or OccupancyMap
        Cell states (1 occupied, 0 free, -1 unknown); the shapes may differ.
    transform : RigidTransform
        Maps moving cells ``(x, y) = (column, row)`` onto reference cells (scale ignored).
    c_lock : float, optional
        Weight of ``disagree - agree`` per cell. Default ``lock_weight / N`` with ``N`` the
        number of known moving cells.
    lock_weight : float
        Used for the default ``c_lock``.

    Returns
    -------
    Dissimilarity
        Delta with its parts, computed on every cell (no subsampling).

    Raises
    ------
    MapError
        If a map is not a valid state grid or the moving map has no known cell.

    References
    ----------
    .. [1] A. Birk and S. Carpin, "Merging occupancy grid maps from multiple robots",
       Proceedings of the IEEE 94(7), 2006.

    Examples
    --------
    >>> import numpy as np
    >>> from brokenness import RigidTransform
    >>> ref = np.zeros((40, 40), np.int8); ref[10, 5:35] = 1; ref[5:35, 20] = 1
    >>> d0 = delta(ref, ref, RigidTransform.identity())
    >>> d1 = delta(ref, ref, RigidTransform(0.0, 3.0, 0.0))
    >>> d0.psi, d0.acceptance
    (0.0, 1.0)
    >>> d0.value < d1.value
    True
    """
    ref = _states(reference, "reference")
    mov = _states(moving, "moving")
    big = max(ref.size, mov.size)
    rt = build_tables(ref, big)
    mt = build_tables(mov, big)
    if mt.n_known == 0:
        raise MapError("the moving map has no occupied or free cell")
    lock = _c_lock(c_lock, lock_weight, mt)
    c, s = math.cos(transform.rotation), math.sin(transform.rotation)
    sc = score(
        rt,
        mt,
        np.array([c]),
        np.array([s]),
        np.array([transform.tx]),
        np.array([transform.ty]),
        lock,
    )
    return Dissimilarity(
        value=float(sc.delta[0]),
        psi=float(sc.psi[0]),
        agree=float(sc.agree[0]),
        disagree=float(sc.disagree[0]),
        acceptance=float(sc.acceptance[0]),
        c_lock=lock,
    )


def _c_lock(c_lock: float | None, lock_weight: float, moving: MapTables) -> float:
    if c_lock is not None:
        return float(c_lock)
    return float(lock_weight) / max(moving.n_known, 1)


# --------------------------------------------------------------------------------------------
# Options, progress
# --------------------------------------------------------------------------------------------
def _check_int(name: str, value: Any, minimum: int = 1) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise ParameterError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def _check_float(name: str, value: Any, *, allow_zero: bool = False) -> float:
    if isinstance(value, bool):
        raise ParameterError(f"{name} must be a number, got {value!r}")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        kind = "non-negative" if allow_zero else "positive"
        raise ParameterError(f"{name} must be a {kind} number, got {value!r}")
    return v


@dataclass(frozen=True)
class WalkOptions:
    """Settings of the adaptive random walk (see the module docstring for their sources).

    Attributes
    ----------
    rotations : int
        Start angles of the coarse grid, evenly spread over 360 degrees (default 12).
    start_grid : int
        Start positions per angle: the centroid-aligned one, the moving map's own position,
        and a ``start_grid x start_grid`` lattice over the reference's known cells
        (default 6; 0 for the first two only).
    walkers_per_angle : int
        The best this many start positions per angle (lowest Delta) each start a walker
        (default 2).
    spectral_starts : int
        Start poses taken from the spectral (iFMI) hypotheses of the same moving map
        (default 6; 0 for the pure stochastic search).
    max_iterations : int
        Iteration budget: lockstep steps of all walkers at most (default 300).
    patience : int
        A walker stalls after this many steps without improving its best Delta by more
        than ``tolerance`` (default 60).
    tolerance : float
        Smallest improvement of Delta that counts as progress (default 0.01).
    restarts : int
        A stalled walker restarts from its best state with the initial step distribution
        at most this many times, then stops (default 2).
    worse_acceptance : float
        Probability of accepting a step that makes Delta worse, in [0, 1) (default 0.05).
    window : int
        Recent steps that the step distribution's mean and covariance are estimated from
        (default 8).
    rotation_step_deg : float
        Standard deviation of the rotation steps before adaptation (default 4).
    translation_step : float, optional
        Same for translation, cells; default 2 % of the reference's larger side (>= 2).
    min_rotation_step_deg, min_translation_step : float
        Floors added to the adapted standard deviations (defaults 0.1 degree, 0.3 cell).
    lock_weight : float
        Default ``c_lock = lock_weight / N`` (``N`` known moving cells); default 10.
    c_lock : float, optional
        Explicit weight of ``disagree - agree`` per cell, overriding ``lock_weight``.
    max_points : int
        Occupied and free cells of each map that take part in the walk's evaluations, at
        most, evenly spaced in row-major order (default 6000; >= 16).
    dedupe_cells : float
        Walkers' results that move every corner of the bounding box of the moving map's
        occupied cells by less than this many cells are one candidate (default 8: the
        recursion refines a candidate by a few cells anyway, so closer ones would crowd
        out the other partitions' alignments).
    explain_cells : float
        An occupied moving cell is *explained* by a transform when it lands within this
        Manhattan distance of an occupied reference cell (default 2, the masking's ``c``);
        candidates are ranked by the cells they explain.
    time_budget : float, optional
        Wall-clock seconds per registration after which the walk stops and returns what it
        has (default none). Makes results machine-dependent: only the iteration budget is
        deterministic.
    search_budget : float, optional
        Evaluations of Delta that all the walks of one search may spend together -- the
        walks of a :meth:`RandomWalkRegistrar.wider` registrar and those of the registrar
        it widens from then on (in ``compute_brokenness``: every walk of the call) -- in
        units of one walk of the registrar it widens (:attr:`nominal_evaluations`); default
        24. Only the wider walks are held to it: a wider walk stops when it is spent, and
        the measure asks a spent registrar for no more wider searches; the plain walks are
        counted but always run. ``None``: no bound (the previous release). See the module
        docstring, "Budgets".

    Raises
    ------
    ParameterError
        For a value out of range.
    """

    rotations: int = 12
    start_grid: int = 6
    walkers_per_angle: int = 2
    spectral_starts: int = 6
    max_iterations: int = 300
    patience: int = 60
    tolerance: float = 0.01
    restarts: int = 2
    worse_acceptance: float = 0.05
    window: int = 8
    rotation_step_deg: float = 4.0
    translation_step: float | None = None
    min_rotation_step_deg: float = 0.1
    min_translation_step: float = 0.3
    lock_weight: float = 10.0
    c_lock: float | None = None
    max_points: int = 6000
    dedupe_cells: float = 8.0
    explain_cells: float = 2.0
    time_budget: float | None = None
    search_budget: float | None = 24.0

    def __post_init__(self) -> None:
        _check_int("rotations", self.rotations)
        _check_int("start_grid", self.start_grid, minimum=0)
        _check_int("walkers_per_angle", self.walkers_per_angle)
        _check_int("spectral_starts", self.spectral_starts, minimum=0)
        _check_int("max_iterations", self.max_iterations)
        _check_int("patience", self.patience)
        _check_float("tolerance", self.tolerance, allow_zero=True)
        _check_int("restarts", self.restarts, minimum=0)
        if _check_float("worse_acceptance", self.worse_acceptance, allow_zero=True) >= 1:
            raise ParameterError(f"worse_acceptance must be below 1, got {self.worse_acceptance!r}")
        _check_int("window", self.window, minimum=2)
        _check_float("rotation_step_deg", self.rotation_step_deg)
        if self.translation_step is not None:
            _check_float("translation_step", self.translation_step)
        _check_float("min_rotation_step_deg", self.min_rotation_step_deg)
        _check_float("min_translation_step", self.min_translation_step)
        _check_float("lock_weight", self.lock_weight, allow_zero=True)
        if self.c_lock is not None:
            _check_float("c_lock", self.c_lock, allow_zero=True)
        _check_int("max_points", self.max_points, minimum=16)
        _check_float("dedupe_cells", self.dedupe_cells, allow_zero=True)
        _check_float("explain_cells", self.explain_cells, allow_zero=True)
        if self.time_budget is not None:
            _check_float("time_budget", self.time_budget)
        if self.search_budget is not None:
            _check_float("search_budget", self.search_budget)

    @property
    def nominal_evaluations(self) -> int:
        """Evaluations of Delta of one full walk with these settings: the coarse grid of start
        poses (``rotations x (2 + start_grid**2)``), then ``max_iterations + 1`` evaluations of
        every walker (``rotations x walkers_per_angle + spectral_starts``) -- the unit of
        ``search_budget``."""
        walkers = self.rotations * self.walkers_per_angle + self.spectral_starts
        return self.rotations * (2 + self.start_grid**2) + (self.max_iterations + 1) * walkers


_OPTION_NAMES = frozenset(f.name for f in fields(WalkOptions))


@dataclass(frozen=True)
class WalkProgress:
    """State of a running walk, as passed to the registrar's ``progress`` callback.

    Attributes
    ----------
    call : int
        Number of :meth:`RandomWalkRegistrar.candidates` calls so far (1 for the first).
    step, max_steps : int
        Lockstep steps done, and the iteration budget.
    walkers, active : int
        Walkers in all, and those still walking.
    best_delta : float
        Lowest Delta found so far (on the sampled cells).
    best_acceptance : float
        Acceptance indicator of that state.
    evaluations : int
        Evaluations of Delta so far.
    seconds : float
        Wall-clock time of this registration so far.
    done : bool
        True for the last report of a registration.
    budget_left : int, optional
        For a walk of a :meth:`RandomWalkRegistrar.wider` registrar, the evaluations left in
        the budget of its search once this walk's are counted (``None`` for the walks of
        other registrars, which the budget does not stop).
    """

    call: int
    step: int
    max_steps: int
    walkers: int
    active: int
    best_delta: float
    best_acceptance: float
    evaluations: int
    seconds: float
    done: bool
    budget_left: int | None = None


ProgressCallback = Callable[[WalkProgress], None]


# --------------------------------------------------------------------------------------------
# The registrar
# --------------------------------------------------------------------------------------------
@dataclass(eq=False)
class _Ledger:
    """Evaluations of Delta left to the walks of one search: a :meth:`RandomWalkRegistrar.wider`
    registrar, which the budget stops, and the registrar it widens, which the budget only
    counts (it may end below 0 by the walk that spent it)."""

    left: int


@dataclass(frozen=True, eq=False)
class _PreparedReference:
    """What :meth:`RandomWalkRegistrar.prepare_reference` computes once."""

    full: MapTables  # every cell
    tables: MapTables  # the walk's sample
    centroid: NDArray[np.float64]
    known_box: tuple[tuple[float, float], tuple[float, float]]
    spectral: Any  # the iFMI prepared reference, or None


#: iFMI options of the spectral start poses: the wider search the recursion falls back on for
#: iFMI itself (a remainder mixes partitions, so many rotation and translation peaks are
#: worth a walker; the walk, not the peak height, decides between them).
_SPECTRAL_OPTIONS: dict[str, Any] = {
    "rotation_peaks": 6,
    "peak_ratio": 0.05,
    "translation_peaks": 3,
}


class RandomWalkRegistrar:
    """Registration by adaptive random walk (Birk & Carpin 2006), the paper's BCMM baseline.

    Parameters
    ----------
    seed : int, optional
        Seed of the walk. ``None`` uses :data:`DEFAULT_SEED`, so that results are always
        repeatable; a fresh ``numpy.random.default_rng(seed)`` stream is created inside
        every :meth:`candidates` call, so the same input gives the same answer bit for bit.
    options : WalkOptions, optional
        The walk's settings (default ``WalkOptions()``).
    progress : callable, optional
        Called with a :class:`WalkProgress` every ``progress_every`` steps and at the end
        of each registration (for a progress display; it must not raise).
    progress_every : int
        Steps between progress reports (default 10).
    **overrides
        Fields of :class:`WalkOptions`, overriding those of ``options`` (so that
        ``make_registrar("random-walk", rotations=8)`` and ``registration_options`` work).

    Raises
    ------
    ParameterError
        For an unknown or out-of-range option.
    """

    name = "random-walk"
    #: Delta uses free cells too, so the recursion should pass them (see measure/recursion).
    uses_free_space = True

    def __init__(
        self,
        *,
        seed: int | None = None,
        options: WalkOptions | None = None,
        progress: ProgressCallback | None = None,
        progress_every: int = 10,
        **overrides: Any,
    ) -> None:
        unknown = sorted(set(overrides) - _OPTION_NAMES)
        if unknown:
            raise ParameterError(f"unknown option(s) for random-walk: {', '.join(unknown)}")
        if seed is None:
            seed = DEFAULT_SEED
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise ParameterError(f"seed must be a non-negative integer or None, got {seed!r}")
        if options is not None and not isinstance(options, WalkOptions):
            raise ParameterError(f"options must be a WalkOptions, got {type(options).__name__}")
        if progress is not None and not callable(progress):
            raise ParameterError("progress must be callable")
        self.seed = int(seed)
        self.options = replace(options or WalkOptions(), **overrides)
        self.progress = progress
        self.progress_every = _check_int("progress_every", progress_every)
        self._calls = 0
        # set by wider(): the budget of the search, shared by the wider registrar (held to it)
        # and the one it widens (counted only)
        self._ledger: _Ledger | None = None
        self._held = False  # whether the walks stop when the ledger is spent

    def __repr__(self) -> str:
        return f"RandomWalkRegistrar(seed={self.seed}, options={self.options!r})"

    # -- Registrar protocol -----------------------------------------------------------------
    def prepare_reference(self, reference_states: NDArray[np.int8]) -> _PreparedReference:
        """Distance maps and sampled cells of the reference (and its spectra), computed once.

        Raises
        ------
        MapError
            If the reference is not a valid state grid or has no occupied cell.
        """
        ref = _states(reference_states, "reference")
        full = build_tables(ref, ref.size)
        if full.counts[0] == 0:
            raise MapError("the reference map has no occupied cell")
        rows, cols = np.nonzero(ref >= 0)
        box = ((float(cols.min()), float(rows.min())), (float(cols.max()), float(rows.max())))
        spectral = None
        if self.options.spectral_starts:
            from .ifmi import IFMIRegistrar

            ifmi = IFMIRegistrar(**_SPECTRAL_OPTIONS)
            spectral = (ifmi, ifmi.prepare_reference(ref))
        return _PreparedReference(
            full=full,
            tables=subsample_tables(full, self.options.max_points),
            centroid=full.centroid,
            known_box=box,
            spectral=spectral,
        )

    def candidates(
        self, prepared_reference: Any, moving_states: NDArray[np.int8], max_candidates: int
    ) -> list[Candidate]:
        """Register a moving map against a prepared reference by adaptive random walk.

        Parameters
        ----------
        prepared_reference
            As returned by :meth:`prepare_reference`.
        moving_states : ndarray of int8
            The moving map (1 occupied, 0 free, -1 unknown).
        max_candidates : int
            At most this many candidates are returned.

        Returns
        -------
        list of Candidate
            Distinct states of the walk (each walker's lowest-Delta state and the one that
            explained the most occupied cells), ranked greedily by the occupied cells they
            explain that better-ranked ones do not, ties by Delta on every cell;
            ``confidence`` and ``acceptance`` are the acceptance indicator
            ``agree / (agree + disagree)`` of the transform.

        Raises
        ------
        MapError
            If the moving map is invalid or has no known cell.
        ParameterError
            If ``max_candidates < 1`` or ``prepared_reference`` is not from this class.
        """
        started = time.perf_counter()
        if not isinstance(prepared_reference, _PreparedReference):
            raise ParameterError(
                "prepared_reference must come from RandomWalkRegistrar.prepare_reference"
            )
        max_candidates = _check_int("max_candidates", max_candidates)
        mov = _states(moving_states, "moving")
        full = build_tables(mov, mov.size)
        if full.n_known == 0:
            raise MapError("the moving map has no occupied or free cell")
        self._calls += 1
        hints = _spectral_hints(prepared_reference, mov, self.options.spectral_starts)
        walk = _walk(
            self,
            prepared_reference,
            subsample_tables(full, self.options.max_points),
            hints,
            started,
        )
        return _to_candidates(walk, prepared_reference, full, self.options, max_candidates)

    @property
    def budget_left(self) -> int | None:
        """Evaluations of Delta left in the budget of the search this registrar's walks are
        counted in (``None`` until :meth:`wider` opens one, and for ``search_budget=None``)."""
        return None if self._ledger is None else self._ledger.left

    @property
    def exhausted(self) -> bool:
        """Whether this :meth:`wider` registrar has spent its search's budget: the measure
        then asks it for no more searches (the registrar it widens is never exhausted)."""
        return self._held and self._ledger is not None and self._ledger.left <= 0

    def wider(self) -> RandomWalkRegistrar:
        """The same walk with twice the start poses: ``walkers_per_angle`` and
        ``spectral_starts`` doubled (0 stays 0: the pure stochastic search stays pure),
        same seed, per-walk budgets and progress callback. It opens the budget of a search:
        ``search_budget`` times :attr:`WalkOptions.nominal_evaluations` of *this*
        registrar's walk (none if ``search_budget`` is ``None``), which every walk of the
        new registrar and, from now on, of this one is counted in; the new registrar's walks
        stop when it is spent, this one's always run.

        The wider search of :func:`brokenness.compute_brokenness` (a step that falls short,
        regions of a heavily broken remainder, the recovery of lost partitions), as iFMI's
        is iFMI with more peaks. It takes the same prepared reference as this registrar. The
        measure makes one per call, before any walk, so the budget bounds the walks of that
        call: once it is spent (:attr:`exhausted`) the measure skips the wider searches, and
        only Algorithm 1's plain walks (one per step and reference) still run.
        """
        opt = self.options
        wide = RandomWalkRegistrar(
            seed=self.seed,
            options=replace(
                opt,
                walkers_per_angle=2 * opt.walkers_per_angle,
                spectral_starts=2 * opt.spectral_starts,
            ),
            progress=self.progress,
            progress_every=self.progress_every,
        )
        if opt.search_budget is not None:
            ledger = _Ledger(math.ceil(opt.search_budget * opt.nominal_evaluations))
            wide._ledger, wide._held = ledger, True
            self._ledger = ledger  # counted in it too (replacing a search opened before)
        return wide

    def register(
        self, reference_states: NDArray[np.int8], moving_states: NDArray[np.int8]
    ) -> Candidate:
        """Convenience: the best candidate of ``moving_states`` against ``reference_states``."""
        return self.candidates(self.prepare_reference(reference_states), moving_states, 1)[0]


def _spectral_hints(
    prepared: _PreparedReference, moving: NDArray[np.int8], count: int
) -> list[RigidTransform]:
    """The iFMI hypotheses of the moving map (rigid part), or none."""
    if not count or prepared.spectral is None or not np.any(moving == 1):
        return []
    registrar, spectral = prepared.spectral
    try:
        found = registrar.candidates(spectral, moving, count)
    except MapError:  # pragma: no cover - guarded by the occupied check above
        return []
    return [RigidTransform(c.transform.rotation, c.transform.tx, c.transform.ty) for c in found]


# --------------------------------------------------------------------------------------------
# The adaptive random walk, all walkers in lockstep
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _WalkResult:
    states: NDArray[np.float64]  # (W, 3) best (theta, ux, uy) per walker
    delta: NDArray[np.float64]  # (W,) on the sampled cells
    most: NDArray[np.float64]  # (W, 3) the state that explained the most cells, per walker
    pivot: NDArray[np.float64]  # moving centroid the rotation turns about
    evaluations: int
    steps: int
    restarts: int
    stopped_by_time: bool
    stopped_by_budget: bool


def _transform_arrays(
    states: NDArray[np.float64], pivot: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """(cos, sin, tx, ty) of ``x -> R(theta) (x - pivot) + u`` for states ``(theta, ux, uy)``."""
    c = np.cos(states[:, 0])
    s = np.sin(states[:, 0])
    tx = states[:, 1] - (c * pivot[0] - s * pivot[1])
    ty = states[:, 2] - (s * pivot[0] + c * pivot[1])
    return c, s, tx, ty


def _state_of(t: RigidTransform, pivot: NDArray[np.float64]) -> NDArray[np.float64]:
    """The walk's state ``(theta, ux, uy)`` of a rigid transform: ``u = t(pivot)``."""
    u = t.apply(pivot[None])[0]
    return np.array([math.remainder(t.rotation, 2 * math.pi), u[0], u[1]])


def _walk(
    reg: RandomWalkRegistrar,
    prepared: _PreparedReference,
    moving: MapTables,
    hints: list[RigidTransform],
    started: float,
) -> _WalkResult:
    opt = reg.options
    ref = prepared.tables
    lock = _c_lock(opt.c_lock, opt.lock_weight, moving)
    pivot = moving.centroid

    def evaluate(st: NDArray[np.float64]) -> Any:
        arrays = _transform_arrays(st, pivot)
        return score(ref, moving, *arrays, lock, explain_cells=opt.explain_cells)

    grid = _start_poses(opt, prepared, pivot, evaluate)
    starts = [grid] + ([np.array([_state_of(t, pivot) for t in hints])] if hints else [])
    state = np.concatenate(starts)
    n_walkers = state.shape[0]

    t_step = opt.translation_step
    if t_step is None:
        t_step = max(2.0, 0.02 * max(ref.shape))
    rot_step = math.radians(opt.rotation_step_deg)
    sigma0 = np.diag([rot_step, t_step, t_step]) ** 2
    rot_floor = math.radians(opt.min_rotation_step_deg)
    floor = np.diag([rot_floor, opt.min_translation_step, opt.min_translation_step]) ** 2
    chol0 = np.linalg.cholesky(sigma0 + floor)
    window = opt.window

    rng = np.random.default_rng(reg.seed)
    first = evaluate(state)
    current = first.delta.copy()
    best_state = state.copy()
    best = current.copy()
    best_acc = first.acceptance.copy()
    most_state = state.copy()  # the state that explained the most cells so far
    most = first.explained.copy()
    mark = current.copy()  # best Delta when the walker last made progress (stopping rule)
    evaluations = opt.rotations * (2 + opt.start_grid**2) + n_walkers  # starts, then walkers
    since = np.zeros(n_walkers, dtype=np.int64)
    restarts = np.zeros(n_walkers, dtype=np.int64)
    mean = np.zeros((n_walkers, 3))
    chol = np.tile(chol0, (n_walkers, 1, 1))
    accepted = np.zeros((n_walkers, window, 3))  # last accepted increments
    n_accepted = np.zeros(n_walkers, dtype=np.int64)
    recent = np.zeros((n_walkers, window, 3))  # last moves, 0 for a rejected proposal
    n_recent = np.zeros(n_walkers, dtype=np.int64)
    active = np.ones(n_walkers, dtype=bool)
    steps = 0
    by_time = by_budget = False
    ledger = reg._ledger
    held = ledger if reg._held else None  # the ledger that stops this walk, if any

    def report(done: bool) -> None:
        if reg.progress is None:
            return
        i = int(np.argmin(best))
        reg.progress(
            WalkProgress(
                call=reg._calls,
                step=steps,
                max_steps=opt.max_iterations,
                walkers=n_walkers,
                active=int(np.count_nonzero(active)),
                best_delta=float(best[i]),
                best_acceptance=float(best_acc[i]),
                evaluations=evaluations,
                seconds=time.perf_counter() - started,
                done=done,
                budget_left=None if held is None else held.left - evaluations,
            )
        )

    report(False)
    while active.any() and steps < opt.max_iterations:
        if opt.time_budget is not None and time.perf_counter() - started > opt.time_budget:
            by_time = True
            break
        if held is not None and evaluations >= held.left:  # the search's budget is spent
            by_budget = True
            break
        steps += 1
        # Draws for every walker, active or not: the stream does not depend on who is done.
        z = rng.standard_normal((n_walkers, 3))
        u = rng.random((n_walkers,))
        idx = np.flatnonzero(active)
        step = mean[idx] + np.einsum("wij,wj->wi", chol[idx], z[idx])
        proposal = state[idx] + step
        proposal[:, 0] = np.angle(np.exp(1j * proposal[:, 0]))  # keep theta in (-pi, pi]
        scored = evaluate(proposal)
        value = scored.delta
        evaluations += idx.size

        improved = value < best[idx]
        progress = value < mark[idx] - opt.tolerance
        best[idx[improved]] = value[improved]
        best_state[idx[improved]] = proposal[improved]
        best_acc[idx[improved]] = scored.acceptance[improved]
        more = scored.explained > most[idx]
        most[idx[more]] = scored.explained[more]
        most_state[idx[more]] = proposal[more]
        mark[idx[progress]] = value[progress]
        since[idx] = np.where(progress, 0, since[idx] + 1)

        accept = (value < current[idx]) | (u[idx] < opt.worse_acceptance)
        acc = idx[accept]
        state[acc] = proposal[accept]
        current[acc] = value[accept]
        accepted[acc, n_accepted[acc] % window] = step[accept]
        n_accepted[acc] += 1
        recent[idx, n_recent[idx] % window] = np.where(accept[:, None], step, 0.0)
        n_recent[idx] += 1
        mean[idx], chol[idx] = _adapt(
            accepted[idx], n_accepted[idx], recent[idx], n_recent[idx], chol0, floor
        )
        # Stalled walkers restart from their best state with the initial step distribution,
        # or stop when they have used up their restarts.
        stalled = active & (since >= opt.patience)
        again = stalled & (restarts < opt.restarts)
        active &= ~(stalled & ~again)
        if again.any():
            state[again] = best_state[again]
            current[again] = best[again]
            mark[again] = best[again]
            since[again] = 0
            restarts[again] += 1
            mean[again] = 0.0
            chol[again] = chol0
            n_accepted[again] = 0
            n_recent[again] = 0
        if steps % reg.progress_every == 0:
            report(False)
    report(True)
    if ledger is not None:
        ledger.left -= evaluations
    return _WalkResult(
        states=best_state,
        delta=best,
        most=most_state,
        pivot=pivot,
        evaluations=evaluations,
        steps=steps,
        restarts=int(restarts.sum()),
        stopped_by_time=by_time,
        stopped_by_budget=by_budget,
    )


def _start_poses(
    opt: WalkOptions,
    prepared: _PreparedReference,
    pivot: NDArray[np.float64],
    evaluate: Any,
) -> NDArray[np.float64]:
    """Deterministic start poses ``(theta, ux, uy)``: the best positions per start angle.

    For each of ``rotations`` evenly spread angles, the moving map's centroid is tried at
    the reference's centroid, at its own position (identity translation) and at the nodes of
    a ``start_grid x start_grid`` lattice over the bounding box of the reference's known
    cells; the ``walkers_per_angle`` lowest-Delta positions start a walker each.
    """
    angles = 2.0 * math.pi * np.arange(opt.rotations) / opt.rotations
    angles = np.angle(np.exp(1j * angles))
    positions = [prepared.centroid, pivot]
    if opt.start_grid:
        (x0, y0), (x1, y1) = prepared.known_box
        frac = (np.arange(opt.start_grid) + 0.5) / opt.start_grid
        gx, gy = np.meshgrid(x0 + frac * (x1 - x0), y0 + frac * (y1 - y0))
        positions.extend(np.column_stack([gx.ravel(), gy.ravel()]))
    pos = np.array(positions)
    n_pos = pos.shape[0]
    grid = np.column_stack([np.repeat(angles, n_pos), np.tile(pos, (opt.rotations, 1))])
    values = evaluate(grid).delta.reshape(opt.rotations, n_pos)
    keep = min(opt.walkers_per_angle, n_pos)
    # Stable order: by Delta, ties by position index.
    order = np.argsort(values, axis=1, kind="stable")[:, :keep]
    chosen = order + (np.arange(opt.rotations) * n_pos)[:, None]
    return grid[chosen.ravel()].copy()


def _adapt(
    accepted: NDArray[np.float64],
    n_accepted: NDArray[np.int64],
    recent: NDArray[np.float64],
    n_recent: NDArray[np.int64],
    chol0: NDArray[np.float64],
    floor: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Mean and Cholesky factor of the step distribution, adapted to the walk's history.

    The covariance is the second moment of the last accepted increments (so the step size
    follows the size of the steps that paid off) plus ``floor``; the mean is the average
    move over the last steps, where a rejected proposal counts as a move of 0 (the walk
    stayed), so the momentum of a successful direction fades once it stops paying off.
    With fewer than two accepted increments the walk keeps its initial distribution.
    """
    window = accepted.shape[1]
    na = np.minimum(n_accepted, window)
    valid = (np.arange(window)[None, :] < na[:, None]).astype(np.float64)
    weighted = accepted * valid[:, :, None]
    cov = np.einsum("wki,wkj->wij", weighted, accepted) / np.maximum(na, 1)[:, None, None]
    chol = np.linalg.cholesky(cov + floor)
    nr = np.maximum(np.minimum(n_recent, window), 1)
    mean = recent.sum(axis=1) / nr[:, None]
    few = na < 2
    mean[few] = 0.0
    chol[few] = chol0
    return mean, chol


def _corners(moving: MapTables) -> NDArray[np.float64]:
    """Corners of the bounding box of the moving map's occupied cells (of all cells if none)."""
    pts = moving.points[0] if moving.points[0].shape[1] else moving.points[1]
    if not pts.shape[1]:  # pragma: no cover - candidates() rejects a map without known cells
        rows, cols = moving.shape
        return np.array([[0.0, 0.0], [cols - 1.0, rows - 1.0]])
    x0, y0 = (float(v) for v in pts[:2].min(axis=1))
    x1, y1 = (float(v) for v in pts[:2].max(axis=1))
    return np.array([[x0, y0], [x1, y0], [x0, y1], [x1, y1]])


def _to_candidates(
    walk: _WalkResult,
    prepared: _PreparedReference,
    moving_full: MapTables,
    opt: WalkOptions,
    max_candidates: int,
) -> list[Candidate]:
    """The walkers' optima that together explain the most, near-duplicates dropped.

    Each walker offers its lowest-Delta state and the state that explained the most
    occupied cells along its walk. They are ranked greedily: first the one that explains
    the most occupied moving cells, then, each time, the one that explains the most cells
    that those before it did not (ties by Delta on every cell). The remainder of a broken
    map has one good alignment per partition; Delta, averaged over all of them, is not
    always lowest at the one that explains the most, and near variants of the best
    alignment explain little that it does not.
    """
    corners = _corners(moving_full)
    states = np.concatenate([walk.states, walk.most])
    c, s, tx, ty = _transform_arrays(states, walk.pivot)
    lock = _c_lock(opt.c_lock, opt.lock_weight, moving_full)
    final = score(prepared.full, moving_full, c, s, tx, ty, lock, explain_cells=opt.explain_cells)
    occupied = subsample_tables(moving_full, opt.max_points).points[0]
    if occupied.shape[1]:
        hits = explained_cells(prepared.full, occupied, c, s, tx, ty, opt.explain_cells)
    else:  # free cells only: rank by Delta
        hits = np.zeros((states.shape[0], 0), dtype=bool)
    covered = np.zeros(hits.shape[1], dtype=bool)
    free = np.ones(states.shape[0], dtype=bool)  # not yet taken or dropped
    kept: list[RigidTransform] = []
    out: list[Candidate] = []
    while free.any() and len(out) < max_candidates:
        gain = np.count_nonzero(hits & ~covered, axis=1)
        pool = np.flatnonzero(free)
        # most new cells, then lowest Delta, then walker order (deterministic)
        i = int(pool[np.lexsort((pool, final.delta[pool], -gain[pool]))[0]])
        free[i] = False
        t = RigidTransform(math.atan2(s[i], c[i]), tx[i], ty[i])
        if any(float(k.displacement(t, corners).max()) < opt.dedupe_cells for k in kept):
            continue
        kept.append(t)
        covered |= hits[i]
        omega = float(np.clip(final.acceptance[i], 0.0, 1.0))
        out.append(Candidate(transform=t, confidence=omega, acceptance=omega))
    return out


# --------------------------------------------------------------------------------------------
# The acceptance indicator of a partition
# --------------------------------------------------------------------------------------------
def partition_acceptance(
    map_states: NDArray[np.int8],
    reference_states: NDArray[np.int8],
    labels: NDArray[np.integer[Any]],
    transforms: list[RigidTransform] | tuple[RigidTransform, ...],
) -> list[float | None]:
    """Birk & Carpin's acceptance indicator ``agree / (agree + disagree)`` per partition.

    A partition's cells are its occupied cells (``labels == i``) and the free cells whose
    nearest labelled occupied cell (Manhattan) belongs to it. Each is moved by the
    partition's transform onto the nearest reference cell; ``agree`` counts those landing on
    a known reference cell of the same state, ``disagree`` on one of the other state.

    Parameters
    ----------
    map_states, reference_states : ndarray of int8
        Cell states (1 occupied, 0 free, -1 unknown) of the map and the reference.
    labels : ndarray of int
        Same shape as the map: partition index of each occupied cell, negative elsewhere.
    transforms : sequence of RigidTransform
        Transform (map cells -> reference cells) of partition ``i`` at position ``i``.

    Returns
    -------
    list of float or None
        One value in [0, 1] per partition, ``None`` when none of its cells lands on known
        reference ground.
    """
    import cv2

    mp = np.asarray(map_states)
    ref = np.asarray(reference_states)
    lab = np.asarray(labels)
    if not transforms:
        return []
    labelled = lab >= 0
    owner = np.where(labelled, lab, -1).astype(np.int64)
    free = mp == 0
    if labelled.any() and free.any():
        # The nearest labelled occupied cell of every cell: OpenCV's labelled two-pass L1
        # distance transform, one label per zero pixel.
        _, nearest = cv2.distanceTransformWithLabels(
            np.where(labelled, 0, 1).astype(np.uint8),
            cv2.DIST_L1,
            3,
            labelType=cv2.DIST_LABEL_PIXEL,
        )
        by_label = np.full(int(nearest.max()) + 1, -1, dtype=np.int64)
        by_label[nearest[labelled]] = lab[labelled]
        owner = np.where(free, by_label[nearest], owner)
    out: list[float | None] = []
    h, w = ref.shape
    for i, t in enumerate(transforms):
        rows, cols = np.nonzero(owner == i)
        if rows.size == 0:
            out.append(None)
            continue
        moved = np.rint(t.apply(np.column_stack([cols, rows]).astype(np.float64))).astype(np.int64)
        inside = (moved[:, 0] >= 0) & (moved[:, 0] < w) & (moved[:, 1] >= 0) & (moved[:, 1] < h)
        landed = np.full(rows.size, -1, dtype=np.int8)
        landed[inside] = ref[moved[inside, 1], moved[inside, 0]]
        known = landed >= 0
        agree = int(np.count_nonzero(known & (landed == mp[rows, cols])))
        total = int(np.count_nonzero(known))
        out.append(agree / total if total else None)
    return out
