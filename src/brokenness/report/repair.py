"""The "repaired" map: every partition moved back onto the reference by its own transform.

A broken map is a set of partitions that are each consistent with the reference but rigidly
off relative to each other. Moving each partition by its own transform (map cells ->
reference cells) puts every piece where it belongs, in the reference's grid: the result shows
what the map would look like without its structural errors. Picture distances Psi of the
map (moved as a whole by the largest partition's transform) and of the repaired map against
the reference say how much of the disagreement the structural errors explain.

Free (and unassigned occupied) cells belong to no partition; each goes with the partition
of its nearest partition cell (Euclidean distance). Where moved pieces overlap, occupied
wins over free, and free over unknown.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from ..errors import MapError
from ..grid import FREE, OCCUPIED, UNKNOWN, OccupancyMap
from ..masking import picture_distance
from ..measure.result import BrokennessResult
from ..transform import RigidTransform

__all__ = ["Repair", "align_map", "partition_owners", "repair", "repair_map", "write_repaired"]

# states encoded so that np.maximum composes pieces: 0 unknown/outside < 1 free < 2 occupied
_ENC_UNKNOWN, _ENC_FREE, _ENC_OCCUPIED = 0, 1, 2


def _encode(states: NDArray[np.int8]) -> NDArray[np.uint8]:
    """States as 0 (unknown or anything else), 1 (free), 2 (occupied): one table lookup, no
    temporary grid."""
    return np.asarray(cv2.LUT(np.ascontiguousarray(states).view(np.uint8), _ENCODE))


def _decode(enc: NDArray[np.uint8]) -> NDArray[np.int8]:
    """0 -> -1 (unknown), 1 -> 0 (free), 2 -> 1 (occupied), in place (``enc`` becomes the
    states; any other byte ``b`` becomes ``int8(b) - 1``, as numpy's wrapping subtraction)."""
    return np.asarray(cv2.LUT(enc, _DECODE, dst=enc)).view(np.int8)


#: Lookup tables of :func:`_encode` (by the state's byte) and :func:`_decode`.
_ENCODE = np.zeros(256, dtype=np.uint8)
_ENCODE[np.uint8(FREE)] = _ENC_FREE
_ENCODE[np.uint8(OCCUPIED)] = _ENC_OCCUPIED
_DECODE = (np.arange(256, dtype=np.uint8).view(np.int8) - np.int8(1)).view(np.uint8)


def _warp(
    enc: NDArray[np.uint8],
    transform: RigidTransform,
    shape: tuple[int, int],
    border: int = _ENC_UNKNOWN,
) -> NDArray:
    rows, cols = shape
    return cv2.warpAffine(
        enc,
        transform.matrix[:2].astype(np.float64),
        (cols, rows),
        flags=cv2.INTER_NEAREST,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=border,
    )


def _check(result: BrokennessResult, map: OccupancyMap) -> NDArray[np.int16]:
    labels = np.asarray(result.labels)
    if labels.shape != map.shape:
        raise MapError(f"result labels have shape {labels.shape} but the map has shape {map.shape}")
    return labels


def align_map(
    map: OccupancyMap, transform: RigidTransform, reference: OccupancyMap
) -> OccupancyMap:
    """The whole map moved by one transform into the reference's grid.

    Parameters
    ----------
    map : OccupancyMap
    transform : RigidTransform
        Map cells -> reference cells.
    reference : OccupancyMap
        Gives the grid (shape, resolution, origin) of the output.

    Returns
    -------
    OccupancyMap
        Same shape and geometry as ``reference``; cells that no map cell lands on are unknown.
    """
    # nearest-neighbour warping only copies cells, so the states' own bytes are warped
    # directly, with unknown's byte outside the map: the same cells as warping the encoded
    # states (:func:`_encode`, a one-to-one relabelling of the three states) and decoding
    unknown = int(np.int8(UNKNOWN).view(np.uint8))
    states = np.ascontiguousarray(map.states).view(np.uint8)
    moved = _warp(states, transform, reference.shape, border=unknown).view(np.int8)
    return _owned_map(moved, reference, map.source)


def _owned_map(
    states: NDArray[np.int8], reference: OccupancyMap, source: str | None
) -> OccupancyMap:
    """A map in the reference's grid of a fresh grid nothing else refers to: made read-only,
    it is taken as it is (a writeable grid would be copied)."""
    states.setflags(write=False)
    return OccupancyMap(states, reference.resolution, reference.origin, source)


def partition_owners(labels: NDArray[np.integer]) -> NDArray[np.int16]:
    """The partition every cell goes with: its own, or that of its nearest partition cell.

    Parameters
    ----------
    labels : ndarray of int, 2D
        Partition index (>= 0) of each partition cell, negative elsewhere.

    Returns
    -------
    ndarray of int16
        Partition index of every cell; all -1 when there is no partition cell.
    """
    labels = np.asarray(labels)
    inside = labels >= 0
    if not inside.any():
        return np.full(labels.shape, -1, dtype=np.int16)
    # cv2 labels every zero pixel of ``src`` with its own number (DIST_LABEL_PIXEL) and every
    # other pixel with the number of its nearest zero pixel; translate numbers to partitions.
    src = np.logical_not(inside).view(np.uint8)  # 0 on the partition cells, 1 elsewhere
    labelled = cv2.distanceTransformWithLabels(src, cv2.DIST_L2, 5, labelType=cv2.DIST_LABEL_PIXEL)
    nearest = labelled[1]
    del labelled, src  # the distances are not needed: dropped at once
    flat = np.flatnonzero(inside.ravel())
    lut = np.full(int(nearest.max()) + 1, -1, dtype=np.int16)
    lut[nearest.ravel()[flat]] = labels.ravel()[flat]
    return lut[nearest]


def repair_map(
    result: BrokennessResult, map: OccupancyMap, reference: OccupancyMap
) -> OccupancyMap:
    """The map with every partition moved back onto the reference by its own transform.

    Parameters
    ----------
    result : BrokennessResult
        The result of :func:`brokenness.compute_brokenness` for ``map`` and ``reference``.
    map, reference : OccupancyMap

    Returns
    -------
    OccupancyMap
        In the reference's grid (shape, resolution, origin). Each partition's occupied cells,
        and the free and unassigned cells nearest to them, moved by the partition's
        transform. Without any partition the map is moved by the identity.

    Raises
    ------
    MapError
        If the result's label image does not have the map's shape.

    Examples
    --------
    >>> fixed = repair_map(result, m, ref)  # doctest: +SKIP
    >>> brokenness.save_map(fixed, "repaired.pgm")  # doctest: +SKIP
    """
    labels = _check(result, map)
    if not result.partitions:
        return align_map(map, RigidTransform.identity(), reference)
    if len(result.partitions) == 1:  # every cell goes with it: the map moved as a whole
        return align_map(map, result.partitions[0].transform, reference)
    owners = partition_owners(labels)
    enc = _encode(map.states)
    out = np.zeros(reference.shape, dtype=np.uint8)
    for p in result.partitions:
        piece = np.where(owners == p.index, enc, np.uint8(_ENC_UNKNOWN))
        np.maximum(out, _warp(piece, p.transform, reference.shape), out=out)
    return _owned_map(_decode(out), reference, map.source)


@dataclass(frozen=True, eq=False)
class Repair:
    """The repaired map and the picture distances that go with it.

    Attributes
    ----------
    repaired : OccupancyMap
        :func:`repair_map` of the result, in the reference's grid.
    aligned : OccupancyMap
        The map moved as a whole by the largest partition's transform (reference grid).
    psi_map : float
        Psi(aligned map, reference), cells.
    psi_repaired : float
        Psi(repaired map, reference), cells. Lower than ``psi_map`` when the structural
        errors explain part of the disagreement.
    """

    repaired: OccupancyMap
    aligned: OccupancyMap
    psi_map: float
    psi_repaired: float

    def to_dict(self) -> dict[str, float]:
        """JSON-ready figures (without the maps)."""
        return {"psi_map": self.psi_map, "psi_repaired": self.psi_repaired}


def repair(result: BrokennessResult, map: OccupancyMap, reference: OccupancyMap) -> Repair:
    """Repaired map plus Psi of the map and of the repaired map against the reference.

    Parameters
    ----------
    result : BrokennessResult
    map, reference : OccupancyMap

    Returns
    -------
    Repair
    """
    labels = _check(result, map)
    del labels
    t0 = result.partitions[0].transform if result.partitions else RigidTransform.identity()
    aligned = align_map(map, t0, reference)
    psi_map = picture_distance(aligned, reference)
    if len(result.partitions) <= 1:  # the repaired map is the aligned one (repair_map)
        return Repair(repaired=aligned, aligned=aligned, psi_map=psi_map, psi_repaired=psi_map)
    repaired = repair_map(result, map, reference)
    return Repair(
        repaired=repaired,
        aligned=aligned,
        psi_map=psi_map,
        psi_repaired=picture_distance(repaired, reference),
    )


def write_repaired(
    path: str | os.PathLike[str],
    result: BrokennessResult,
    map: OccupancyMap,
    reference: OccupancyMap,
) -> Repair:
    """Repair the map, save it with :func:`brokenness.save_map` and return the figures.

    One call for ``brokenness compute --repaired out.pgm``: the format follows the suffix
    (a ``.pgm``/``.png`` with a ``.yaml`` next to it when the reference has geometry, as
    ``save_map`` does).

    Returns
    -------
    Repair
    """
    from ..io import save_map  # late: io is a sibling package written independently

    rep = repair(result, map, reference)
    save_map(rep.repaired, path)
    return rep
