"""The paper's baseline registration: Birk & Carpin's map merging by adaptive random walk.

Birk (ICRA 2010) compares the spectral registration with the map-merging method of Birk &
Carpin (2006), called BCMM in the paper's tables: a stochastic search over rigid transforms
``(theta, tx, ty)`` that minimises the dissimilarity

.. math::

    \\Delta(T) = \\Psi(T(m), r) + c_{lock} \\, (\\mathrm{dis}(T(m), r) - \\mathrm{agr}(T(m), r))

where ``Psi`` is the picture distance (Manhattan distances to the nearest cell of the same
kind, both ways; see :func:`brokenness.picture_distance`), ``agr`` counts the cells known in
both maps that hold the same state and ``dis`` those that hold different states (occupied vs
free). The *acceptance indicator* ``omega = agr / (agr + dis)`` judges the result.

What is taken from where
------------------------
- ``Delta``, ``agr``, ``dis``, ``omega``, the weight ``c_lock`` and the picture distance
  ``Psi`` (sum over occupied and free cells, both directions, of the mean Manhattan distance
  to the nearest cell of the same kind): Birk & Carpin (2006), as summarised by Birk (2010).
  Here ``Psi`` is restricted to the overlap (cells whose counterpart under ``T`` is known),
  because in the recursion of Algorithm 1 the moving map is often only a part of the
  reference; the lock term rewards a large overlap.
- The search: an adaptive random walk in the sense of Carpin & Pillonetto (2005), as Birk &
  Carpin (2006) use it: Gaussian increments in ``(theta, tx, ty)`` whose mean and covariance
  adapt to the walk's recent accepted steps; an improving step is always accepted, a worse
  one with a small fixed probability ``worse_acceptance``. The exact update rule is ours:
  the covariance is the second moment of the last ``window`` accepted increments (step
  sizes follow the steps that paid off) plus a floor, and the mean is the average move of
  the last ``window`` steps counting a rejected proposal as a move of 0. (A mean that only
  averages accepted increments keeps pushing in its last direction forever once the walk
  sits in an optimum, and we saw the walk drift out of the optimum that way.) Rotation
  turns about the moving map's centroid, so that the three coordinates are decoupled.
- Restarts: several walkers, the best one wins. Their start poses are ours and
  deterministic: ``rotations`` evenly spread angles, and per angle the ``walkers_per_angle``
  best (lowest Delta) of a few start positions for the moving map's centroid (the
  reference's centroid, its own position, a ``start_grid x start_grid`` lattice over the
  reference's known cells).
- The stopping rule (a walker stops after ``patience`` steps that did not improve its best
  Delta by more than ``tolerance``, or after ``max_iterations``), the step sizes and the
  default ``c_lock`` are our choices, tuned on the maps in ``tests/data``: the numerical
  values of the original implementation were not available to us. The default
  ``c_lock = lock_weight / N`` (``N`` known moving cells) makes a perfect full overlap worth
  ``lock_weight`` cells of picture distance whatever the map size.
- Subsampling (ours): when a map has more than ``max_points`` occupied (or free) cells, an
  evenly spaced subset of them (row-major order, independent of the seed) takes part, and
  ``agr``/``dis`` are scaled back to cells.

Known limitation (of the method, not the implementation): when the moving map holds several
partitions, ``Psi`` averages over all of them, so the minimum of Delta can sit a fraction of
a degree away from the best transform of the largest partition; the recursion refines the
chosen candidate anyway.

Cost of one evaluation: the distance maps of the reference are computed once by
:meth:`RandomWalkRegistrar.prepare_reference`, those of the moving map once per
:meth:`RandomWalkRegistrar.candidates` call; an evaluation transforms only the coordinates of
the (at most ``max_points`` per kind, deterministically subsampled) occupied and free cells
of both maps and looks distances up, all walkers of a step at once.

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
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import MapError, ParameterError
from ..grid import OccupancyMap
from ..transform import RigidTransform
from ._rw_scoring import MapTables, build_tables, score
from .base import Candidate

__all__ = ["DEFAULT_SEED", "Dissimilarity", "RandomWalkRegistrar", "delta"]

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
# The registrar
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class _PreparedReference:
    """What :meth:`RandomWalkRegistrar.prepare_reference` computes once."""

    tables: MapTables
    centroid: NDArray[np.float64]
    known_box: tuple[tuple[float, float], tuple[float, float]]


def _positive_int(name: str, value: Any, minimum: int = 1) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise ParameterError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def _positive_float(name: str, value: Any, *, allow_zero: bool = False) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        raise ParameterError(
            f"{name} must be a {'non-negative' if allow_zero else 'positive'} number, got {value!r}"
        )
    return v


class RandomWalkRegistrar:
    """Registration by adaptive random walk (Birk & Carpin 2006), the paper's BCMM baseline.

    Parameters
    ----------
    seed : int, optional
        Seed of the walk. ``None`` uses :data:`DEFAULT_SEED`, so that results are always
        repeatable; the generator is created afresh inside every :meth:`candidates` call, so
        the same input gives the same answer bit for bit.
    rotations : int
        Number of start angles, evenly spread over 360 degrees (default 12).
    start_grid : int
        Start positions tried per angle: the centroid-aligned one, the moving map's own
        position, and a ``start_grid x start_grid`` lattice over the reference's known cells
        (default 6; 0 for the first two only).
    walkers_per_angle : int
        The best this many start positions per angle (lowest Delta) each start a walker
        (default 2): ``rotations * walkers_per_angle`` walkers in all.
    max_iterations : int
        Steps per walker at most (default 1500).
    patience : int
        A walker stops after this many steps without improving its best Delta by more than
        ``tolerance`` (default 100).
    tolerance : float
        Smallest improvement of Delta that counts for the stopping rule (default 0.01).
    worse_acceptance : float
        Probability of accepting a step that makes Delta worse (default 0.05).
    window : int
        Number of recent accepted increments that the step distribution's mean and covariance
        are estimated from (default 8).
    rotation_step_deg : float
        Standard deviation of the rotation steps before any step was accepted (default 4).
    translation_step : float, optional
        Same for translation, in cells; default 2 % of the reference's larger side (>= 2).
    min_rotation_step_deg, min_translation_step : float
        Floors added to the adapted standard deviations, so that the walk never freezes
        (defaults 0.1 degree and 0.3 cell).
    lock_weight : float
        Default ``c_lock = lock_weight / N`` (``N`` known moving cells); default 10.
    c_lock : float, optional
        Explicit weight of ``disagree - agree`` per cell, overriding ``lock_weight``.
    max_points : int
        At most this many occupied and this many free cells of each map take part in an
        evaluation, evenly spaced in row-major order (default 20000; the counts are scaled
        back to cells).
    dedupe_cells : float
        Walkers' results that move every corner of the moving map by less than this many
        cells are one candidate (default 3).

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
        rotations: int = 12,
        start_grid: int = 6,
        walkers_per_angle: int = 2,
        max_iterations: int = 1500,
        patience: int = 100,
        tolerance: float = 0.01,
        worse_acceptance: float = 0.05,
        window: int = 8,
        rotation_step_deg: float = 4.0,
        translation_step: float | None = None,
        min_rotation_step_deg: float = 0.1,
        min_translation_step: float = 0.3,
        lock_weight: float = 10.0,
        c_lock: float | None = None,
        max_points: int = 20000,
        dedupe_cells: float = 3.0,
        **unknown: Any,
    ) -> None:
        if unknown:
            raise ParameterError(f"unknown option(s) for random-walk: {', '.join(sorted(unknown))}")
        if seed is None:
            seed = DEFAULT_SEED
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise ParameterError(f"seed must be a non-negative integer or None, got {seed!r}")
        self.seed = int(seed)
        self.rotations = _positive_int("rotations", rotations)
        self.start_grid = _positive_int("start_grid", start_grid, minimum=0)
        self.walkers_per_angle = _positive_int("walkers_per_angle", walkers_per_angle)
        self.max_iterations = _positive_int("max_iterations", max_iterations)
        self.patience = _positive_int("patience", patience)
        self.tolerance = _positive_float("tolerance", tolerance, allow_zero=True)
        p = _positive_float("worse_acceptance", worse_acceptance, allow_zero=True)
        if p >= 1:
            raise ParameterError(f"worse_acceptance must be below 1, got {worse_acceptance!r}")
        self.worse_acceptance = p
        self.window = _positive_int("window", window, minimum=2)
        self.rotation_step = math.radians(_positive_float("rotation_step_deg", rotation_step_deg))
        self.translation_step = (
            None
            if translation_step is None
            else _positive_float("translation_step", translation_step)
        )
        self.min_rotation_step = math.radians(
            _positive_float("min_rotation_step_deg", min_rotation_step_deg)
        )
        self.min_translation_step = _positive_float("min_translation_step", min_translation_step)
        self.lock_weight = _positive_float("lock_weight", lock_weight, allow_zero=True)
        self.c_lock = None if c_lock is None else _positive_float("c_lock", c_lock, allow_zero=True)
        self.max_points = _positive_int("max_points", max_points, minimum=16)
        self.dedupe_cells = _positive_float("dedupe_cells", dedupe_cells, allow_zero=True)

    def __repr__(self) -> str:
        return f"RandomWalkRegistrar(seed={self.seed}, rotations={self.rotations})"

    # -- Registrar protocol -----------------------------------------------------------------
    def prepare_reference(self, reference_states: NDArray[np.int8]) -> _PreparedReference:
        """Distance maps and sampled cells of the reference, computed once.

        Raises
        ------
        MapError
            If the reference is not a valid state grid or has no occupied cell.
        """
        ref = _states(reference_states, "reference")
        tables = build_tables(ref, self.max_points)
        if tables.counts[0] == 0:
            raise MapError("the reference map has no occupied cell")
        rows, cols = np.nonzero(ref >= 0)
        box = ((float(cols.min()), float(rows.min())), (float(cols.max()), float(rows.max())))
        return _PreparedReference(tables=tables, centroid=tables.centroid, known_box=box)

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
            Distinct final poses of the walkers, lowest Delta first; ``confidence`` is the
            acceptance indicator ``agree / (agree + disagree)`` of the transform.

        Raises
        ------
        MapError
            If the moving map is invalid or has no known cell.
        ParameterError
            If ``max_candidates < 1`` or ``prepared_reference`` is not from this class.
        """
        if not isinstance(prepared_reference, _PreparedReference):
            raise ParameterError(
                "prepared_reference must come from RandomWalkRegistrar.prepare_reference"
            )
        max_candidates = _positive_int("max_candidates", max_candidates)
        mov = _states(moving_states, "moving")
        moving = build_tables(mov, self.max_points)
        if moving.n_known == 0:
            raise MapError("the moving map has no occupied or free cell")
        walk = _walk(self, prepared_reference, moving)
        return _to_candidates(walk, moving, self.dedupe_cells, max_candidates)

    def register(
        self, reference_states: NDArray[np.int8], moving_states: NDArray[np.int8]
    ) -> Candidate:
        """Convenience: the best candidate of ``moving_states`` against ``reference_states``."""
        return self.candidates(self.prepare_reference(reference_states), moving_states, 1)[0]


# --------------------------------------------------------------------------------------------
# The adaptive random walk, all walkers in lockstep
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _WalkResult:
    states: NDArray[np.float64]  # (W, 3) best (theta, ux, uy) per walker
    delta: NDArray[np.float64]  # (W,)
    acceptance: NDArray[np.float64]  # (W,)
    pivot: NDArray[np.float64]  # moving centroid the rotation turns about
    evaluations: int
    steps: int


def _transform_arrays(
    states: NDArray[np.float64], pivot: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """(cos, sin, tx, ty) of ``x -> R(theta) (x - pivot) + u`` for states ``(theta, ux, uy)``."""
    c = np.cos(states[:, 0])
    s = np.sin(states[:, 0])
    tx = states[:, 1] - (c * pivot[0] - s * pivot[1])
    ty = states[:, 2] - (s * pivot[0] + c * pivot[1])
    return c, s, tx, ty


def _walk(reg: RandomWalkRegistrar, prepared: _PreparedReference, moving: MapTables) -> _WalkResult:
    ref = prepared.tables
    lock = _c_lock(reg.c_lock, reg.lock_weight, moving)
    pivot = moving.centroid

    def evaluate(st: NDArray[np.float64]) -> Any:
        return score(ref, moving, *_transform_arrays(st, pivot), lock)

    state = _start_poses(reg, prepared, pivot, evaluate)
    n_walkers = state.shape[0]

    t_step = reg.translation_step
    if t_step is None:
        t_step = max(2.0, 0.02 * max(ref.shape))
    sigma0 = np.diag([reg.rotation_step, t_step, t_step]) ** 2
    floor = (
        np.diag([reg.min_rotation_step, reg.min_translation_step, reg.min_translation_step]) ** 2
    )
    chol0 = np.linalg.cholesky(sigma0 + floor)

    rng = np.random.default_rng(reg.seed)
    current = evaluate(state).delta
    best_state = state.copy()
    best = current.copy()
    mark = current.copy()  # best Delta when the walker last made progress (stopping rule)
    evaluations = n_walkers
    since = np.zeros(n_walkers, dtype=np.int64)
    mean = np.zeros((n_walkers, 3))
    chol = np.tile(chol0, (n_walkers, 1, 1))
    accepted = np.zeros((n_walkers, reg.window, 3))  # last accepted increments
    n_accepted = np.zeros(n_walkers, dtype=np.int64)
    recent = np.zeros((n_walkers, reg.window, 3))  # last moves, 0 for a rejected proposal
    n_recent = np.zeros(n_walkers, dtype=np.int64)
    active = np.ones(n_walkers, dtype=bool)
    steps = 0
    while active.any() and steps < reg.max_iterations:
        steps += 1
        z = rng.standard_normal((n_walkers, 3))
        u = rng.random((n_walkers,))
        idx = np.flatnonzero(active)
        step = mean[idx] + np.einsum("wij,wj->wi", chol[idx], z[idx])
        proposal = state[idx] + step
        proposal[:, 0] = np.angle(np.exp(1j * proposal[:, 0]))  # keep theta in (-pi, pi]
        value = evaluate(proposal).delta
        evaluations += idx.size

        improved = value < best[idx]
        progress = value < mark[idx] - reg.tolerance
        best[idx[improved]] = value[improved]
        best_state[idx[improved]] = proposal[improved]
        mark[idx[progress]] = value[progress]
        since[idx] = np.where(progress, 0, since[idx] + 1)

        accept = (value < current[idx]) | (u[idx] < reg.worse_acceptance)
        acc = idx[accept]
        state[acc] = proposal[accept]
        current[acc] = value[accept]
        accepted[acc, n_accepted[acc] % reg.window] = step[accept]
        n_accepted[acc] += 1
        recent[idx, n_recent[idx] % reg.window] = np.where(accept[:, None], step, 0.0)
        n_recent[idx] += 1
        mean[idx], chol[idx] = _adapt(
            accepted[idx], n_accepted[idx], recent[idx], n_recent[idx], chol0, floor
        )
        active &= since < reg.patience

    final = evaluate(best_state)
    return _WalkResult(
        states=best_state,
        delta=final.delta,
        acceptance=final.acceptance,
        pivot=pivot,
        evaluations=evaluations + n_walkers,
        steps=steps,
    )


def _start_poses(
    reg: RandomWalkRegistrar,
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
    angles = 2.0 * math.pi * np.arange(reg.rotations) / reg.rotations
    positions = [prepared.centroid, pivot]
    if reg.start_grid:
        (x0, y0), (x1, y1) = prepared.known_box
        frac = (np.arange(reg.start_grid) + 0.5) / reg.start_grid
        gx, gy = np.meshgrid(x0 + frac * (x1 - x0), y0 + frac * (y1 - y0))
        positions.extend(np.column_stack([gx.ravel(), gy.ravel()]))
    pos = np.array(positions)
    n_pos = pos.shape[0]
    grid = np.column_stack([np.repeat(angles, n_pos), np.tile(pos, (reg.rotations, 1))])
    values = evaluate(grid).delta.reshape(reg.rotations, n_pos)
    keep = min(reg.walkers_per_angle, n_pos)
    # Stable order: by Delta, ties by position index.
    order = np.argsort(values, axis=1, kind="stable")[:, :keep]
    chosen = order + (np.arange(reg.rotations) * n_pos)[:, None]
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


def _to_candidates(
    walk: _WalkResult, moving: MapTables, dedupe_cells: float, max_candidates: int
) -> list[Candidate]:
    """Walkers' best poses, lowest Delta first, near-duplicates dropped."""
    rows, cols = moving.shape
    corners = np.array([[0.0, 0.0], [cols - 1.0, 0.0], [0.0, rows - 1.0], [cols - 1.0, rows - 1.0]])
    c, s, tx, ty = _transform_arrays(walk.states, walk.pivot)
    order = np.lexsort((np.arange(walk.delta.size), walk.delta))
    kept: list[int] = []
    out: list[Candidate] = []
    for i in order:
        t = RigidTransform(math.atan2(s[i], c[i]), tx[i], ty[i])
        if any(
            float(
                RigidTransform(math.atan2(s[j], c[j]), tx[j], ty[j]).displacement(t, corners).max()
            )
            < dedupe_cells
            for j in kept
        ):
            continue
        kept.append(int(i))
        out.append(Candidate(transform=t, confidence=float(np.clip(walk.acceptance[i], 0.0, 1.0))))
        if len(out) >= max_candidates:
            break
    return out
