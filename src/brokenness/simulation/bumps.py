"""Bump noise on a robot's pose estimate (Birk 2010, Sec. I).

The paper's model: at each time step, with a small probability ``p_B``, the estimated pose
jumps by a rotation ``theta ~ U[0, 2 pi)`` and a shift ``d ~ U[0, r]``; otherwise nothing
happens. A bump at scan ``i`` turns the estimate by ``theta`` about the robot's estimated
position at scan ``i`` and then shifts it by ``d`` in a uniformly random direction. The
error composes onto the pose chain: every later pose estimate carries the accumulated world
error ``E_j`` (estimated pose = ``E_j`` o true pose), so ``k`` bumps split the run into
``k + 1`` segments, each mapped rigidly "off" from the others.

:func:`draw_bumps` is the paper's per-scan model, :func:`draw_k_bumps` the exact "k bumps"
mode for test sets, :func:`apply_bumps` composes bumps onto a pose chain.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ParameterError

__all__ = ["Bump", "BumpedPoses", "apply_bumps", "draw_bumps", "draw_k_bumps", "rigid_matrix"]


@dataclass(frozen=True)
class Bump:
    """One jump of the pose estimate.

    Attributes
    ----------
    scan : int
        Index of the first scan drawn with the new error.
    theta : float
        Rotation of the estimate, radians (counter-clockwise, about the estimated position).
    d : float
        Length of the shift, metres.
    direction : float
        Direction of the shift in the world frame, radians.
    counted : bool
        Whether the partition this bump starts counts towards the expected degree.
    reason : str
        Why it does not count (empty when it does).
    """

    scan: int
    theta: float
    d: float
    direction: float
    counted: bool = True
    reason: str = ""

    def with_verdict(self, counted: bool, reason: str = "") -> Bump:
        """A copy with the verdict of the honesty rule."""
        return replace(self, counted=counted, reason=reason)

    def to_dict(self) -> dict[str, object]:
        """JSON-ready dictionary (angles in degrees)."""
        return {
            "scan": self.scan,
            "theta_deg": math.degrees(self.theta),
            "d_m": self.d,
            "direction_deg": math.degrees(self.direction),
            "counted": self.counted,
            "reason": self.reason,
        }


@dataclass(frozen=True, eq=False)
class BumpedPoses:
    """A pose chain with bumps composed onto it.

    Attributes
    ----------
    poses : ndarray, shape (N, 3)
        The estimated poses.
    segment : ndarray of int, shape (N,)
        Index of the segment (partition) each scan belongs to: 0 before the first bump.
    errors : tuple of ndarray, each 3x3
        World error ``E_j`` of each segment (homogeneous matrix, metres): estimated pose =
        ``E_j`` o input pose.
    bumps : tuple of Bump
        The bumps, sorted by scan; bump ``j`` starts segment ``j + 1``.
    """

    poses: NDArray[np.float64]
    segment: NDArray[np.int64]
    errors: tuple[NDArray[np.float64], ...]
    bumps: tuple[Bump, ...]


def rigid_matrix(theta: float, tx: float, ty: float) -> NDArray[np.float64]:
    """3x3 homogeneous matrix of a rotation by ``theta`` followed by a shift ``(tx, ty)``."""
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s, tx], [s, c, ty], [0.0, 0.0, 1.0]])


def _check(radius: float, max_rotation: float) -> None:
    if not (math.isfinite(radius) and radius >= 0):
        raise ParameterError(f"bump radius must be a non-negative number of metres, got {radius}")
    if not (math.isfinite(max_rotation) and 0 <= max_rotation <= math.pi):
        raise ParameterError(f"max rotation must be in [0, pi] radians, got {max_rotation}")


def _theta(rng: np.random.Generator, max_rotation: float, min_rotation: float = 0.0) -> float:
    if max_rotation >= math.pi and min_rotation == 0.0:
        return float(rng.uniform(0.0, 2.0 * math.pi))  # the paper's U[0, 2 pi)
    magnitude = float(rng.uniform(min_rotation, max_rotation))
    return magnitude if rng.random() < 0.5 else -magnitude


def _bump(
    rng: np.random.Generator,
    scan: int,
    radius: float,
    max_rotation: float,
    min_rotation: float = 0.0,
) -> Bump:
    """One bump at ``scan``: the turn, then the shift's length and direction, in this order."""
    theta = _theta(rng, max_rotation, min_rotation)
    return Bump(
        scan, theta, float(rng.uniform(0.0, radius)), float(rng.uniform(0.0, 2.0 * math.pi))
    )


def draw_bumps(
    n_scans: int,
    probability: float,
    *,
    radius: float,
    max_rotation: float = math.pi,
    rng: np.random.Generator,
    margin: int = 1,
) -> list[Bump]:
    """The paper's bump noise: each scan bumps with probability ``probability``.

    Parameters
    ----------
    n_scans : int
    probability : float
        ``p_B`` in [0, 1].
    radius : float
        ``r``: shifts are ``d ~ U[0, r]`` metres in a uniformly random direction.
    max_rotation : float
        Radians. ``pi`` (default) draws ``theta ~ U[0, 2 pi)`` as the paper does; a smaller
        value draws ``theta ~ U[-max_rotation, max_rotation]``.
    rng : numpy.random.Generator
    margin : int
        The first ``margin`` scans never bump (a bump at scan 0 is no error).

    Returns
    -------
    list of Bump
        Sorted by scan.
    """
    if not (0.0 <= probability <= 1.0):
        raise ParameterError(f"bump probability must be in [0, 1], got {probability}")
    _check(radius, max_rotation)
    events = rng.random(n_scans) < probability
    events[: max(margin, 0)] = False
    return [_bump(rng, int(i), radius, max_rotation) for i in np.flatnonzero(events)]


def draw_k_bumps(
    n_scans: int,
    k: int,
    *,
    radius: float,
    max_rotation: float = math.pi,
    min_rotation: float = 0.0,
    rng: np.random.Generator,
    margin: float = 0.05,
    spread: bool = True,
) -> list[Bump]:
    """Exactly ``k`` bumps at distinct scans, away from the start and end of the run.

    Parameters
    ----------
    n_scans, k : int
    radius, max_rotation
        As :func:`draw_bumps`.
    min_rotation : float
        Smallest ``|theta|``, radians (the sign is random).
    rng : numpy.random.Generator
    margin : float
        Share of the run at each end where no bump falls.
    spread : bool
        True: bump ``i`` falls near the fraction ``(i + 1) / (k + 1)`` of the run (jittered
        by up to a third of the spacing), so the partitions have comparable lengths. False:
        indices drawn uniformly without replacement.

    Returns
    -------
    list of Bump
        Sorted by scan.
    """
    _check(radius, max_rotation)
    if not (0.0 <= min_rotation <= max_rotation):
        raise ParameterError("min rotation must be in [0, max rotation]")
    lo = int(math.ceil(margin * n_scans))
    hi = int(math.floor((1.0 - margin) * n_scans))
    if k < 0 or (k > 0 and hi - lo < k):
        raise ParameterError(f"cannot place {k} bumps in a run of {n_scans} scans")
    if k == 0:
        return []
    if spread:
        frac = (np.arange(1, k + 1) + rng.uniform(-1 / 3, 1 / 3, k)) / (k + 1)
        idx = np.clip(np.rint(lo + frac * (hi - lo)).astype(np.int64), lo, hi - 1)
        step = np.arange(k)
        idx = np.maximum.accumulate(idx - step) + step  # strictly increasing: distinct scans
        idx = np.unique(np.clip(idx, lo, hi - 1))
        if len(idx) < k:  # too short a run for a jittered spread: fall back to a draw
            idx = np.sort(rng.choice(np.arange(lo, hi), size=k, replace=False))
    else:
        idx = np.sort(rng.choice(np.arange(lo, hi), size=k, replace=False))
    return [_bump(rng, int(i), radius, max_rotation, min_rotation) for i in idx]


def apply_bumps(poses: ArrayLike, bumps: Sequence[Bump]) -> BumpedPoses:
    """Compose bumps onto a pose chain.

    Parameters
    ----------
    poses : array_like, shape (N, 3)
        The (bump-free) pose estimate ``x, y, theta``.
    bumps : sequence of Bump
        Scans must be distinct and in ``[1, N)``.

    Returns
    -------
    BumpedPoses
    """
    p = np.asarray(poses, dtype=float).reshape(-1, 3)
    ordered = tuple(sorted(bumps, key=lambda b: b.scan))
    scans = [b.scan for b in ordered]
    if len(set(scans)) != len(scans) or any(not (1 <= s < len(p)) for s in scans):
        raise ParameterError(f"bump scans must be distinct and in [1, {len(p)}), got {scans}")
    errors = [np.eye(3)]
    segment = np.zeros(len(p), dtype=np.int64)
    for j, b in enumerate(ordered):
        e = errors[-1]
        q = e @ np.array([p[b.scan, 0], p[b.scan, 1], 1.0])  # estimated position, before
        rot_about_q = rigid_matrix(b.theta, 0.0, 0.0)
        rot_about_q[:2, 2] = q[:2] - rot_about_q[:2, :2] @ q[:2]
        shift = rigid_matrix(0.0, b.d * math.cos(b.direction), b.d * math.sin(b.direction))
        errors.append(shift @ rot_about_q @ e)
        segment[b.scan :] = j + 1
    out = np.empty_like(p)
    for j, e in enumerate(errors):
        sel = segment == j
        out[sel, :2] = p[sel, :2] @ e[:2, :2].T + e[:2, 2]
        out[sel, 2] = p[sel, 2] + math.atan2(e[1, 0], e[0, 0])
    out[:, 2] = np.remainder(out[:, 2] + math.pi, 2 * math.pi) - math.pi
    return BumpedPoses(poses=out, segment=segment, errors=tuple(errors), bumps=ordered)
