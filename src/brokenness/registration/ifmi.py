"""Improved Fourier-Mellin (iFMI) registration of occupancy grids.

The method of Buelow & Birk (ref. 38 of the paper; after Reddy & Chatterji 1996), for a
rigid transform (rotation + translation, scale 1):

1. **Image.** Each map becomes its *occupied* indicator (1.0 for occupied cells, 0.0 for
   free and unknown). Occupied cells are the structure two maps of the same place share;
   free space depends on where the robot drove and unknown cells on how far it saw, so
   both would add content that does not register. Both maps are cropped to the bounding
   box of their occupied cells, which shrinks every FFT below, and max-pooled by an
   integer factor so that the rotation stage sees at most about ``rotation_size`` cells per
   side and the translation stage ``max_size`` (a wall one cell thick survives
   max-pooling, it would fade under averaging). The full resolution is used again in 4.
2. **Rotation.** Hann window, FFT, *logarithm* of the magnitude (the first iFMI
   improvement: the few strong low frequencies no longer drown the directional structure),
   a *band filter* on the spectrum (the second improvement: only radii in ``band``, as
   fractions of Nyquist, are kept -- the lowest carry the map's overall shape and the
   window, the highest the aliasing of the grid), resampled on a polar grid. The magnitude
   does not depend on the translation, and a rotation of the map turns it by the same angle,
   so phase correlation along the angle axis (summed over the radii of the band) peaks at
   the rotation; the peak is refined to sub-bin precision by a parabola. The cross-power
   spectrum is divided by the *square root* of its magnitude (``rotation_whitening``), not
   by the magnitude itself: a map whose parts are turned by different angles (a broken
   map) gives one peak per part, and full whitening flattens them to nearly equal heights
   -- on simulated broken maps of degrees 2-5 the angle of the largest part was among the
   three highest peaks in 50 % of the maps, against 66 % with the square root (91 % against
   66 % for the highest peak being some part's angle). Because the
   magnitude of a real image is point-symmetric, angles are only known modulo 180 degrees:
   each of the ``rotation_peaks`` best peaks yields two hypotheses, ``t`` and ``t + 180``.
3. **Translation.** For each hypothesis the moving image is rotated (``cv2.remap`` of a
   map computed in numpy, which gives the same bits on any number of threads) and
   phase-correlated with the reference; both are zero-padded to at least the sum of
   their extents (even sizes OpenCV transforms fast) so that no shift wraps around. The
   180-degree twin needs no second forward FFT: flipping a real image through the origin
   conjugates its spectrum (OpenCV's real DFT in its packed layout, see
   :mod:`brokenness.registration._spectral`). The peak is refined to sub-cell precision by
   a parabola per axis; its height over the mean and spread of the correlation surface (a
   z-score, less the level noise peaks reach) is the hypothesis' peak quality and gives
   its confidence.
4. **Refinement** (``refine=True``). The estimate of the reduced images is polished at
   full resolution by a Gauss-Newton fit of the outline cells of the moving map's walls
   to the distance map of the reference's outlines, counting only cells that already lie
   near a reference wall (:mod:`brokenness.registration._refine`). Hypotheses are ranked by
   the number of the moving map's outline cells that then lie within ``agree_cells`` of a
   reference outline (the part of the map the transform explains -- what the recursion of
   Algorithm 1 keeps), ties by the peak quality.

Transforms map moving cells ``(x, y) = (column, row)`` onto reference cells
(:mod:`brokenness.transform`): the rotation about the image centre used in 3 and the
offsets of the crops and pooling are folded into the canonical ``x' = R x + t``.

Everything is deterministic: no random numbers, fixed subsampling, ties broken by index, and
no OpenCV call whose result depends on its number of threads (``cv2.warpAffine``'s bilinear
warp and ``cv2.meanStdDev`` of a large image do: see :func:`_draw_turned`), so a batch worker
on one thread and a call on every core give the same bits.

References
----------
.. [1] H. Buelow and A. Birk, "Fast and robust photomapping with an unmanned aerial
   vehicle (UAV)", IEEE/RSJ IROS 2009.
.. [2] B. S. Reddy and B. N. Chatterji, "An FFT-based technique for translation, rotation,
   and scale-invariant image registration", IEEE Trans. Image Processing 5(8), 1996.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np
import scipy.fft
from numpy.typing import NDArray

from .._points import squared_norms, take_rows
from ..errors import MapError, ParameterError
from ..grid import OCCUPIED
from ..transform import RigidTransform
from . import _refine, _spectral
from .base import Candidate, OccupiedCells

__all__ = ["IFMIRegistrar"]

#: Padded sizes whose reference spectrum a prepared reference keeps (moving maps of
#: different extents need different paddings; the recursion registers a handful).
_SPECTRA_CACHED = 8
#: Moving maps whose analysis a prepared reference remembers.
_MEMOS = 2
#: Cells of margin the reference's distance map keeps around its walls' bounding box; more
#: than any inlier radius of the refinement (which starts at ``2 * factor + 2`` cells).
_DISTANCE_MARGIN = 64
#: Two placements whose centroids are farther apart than this (squared: a cell and a
#: margin for rounding, :meth:`IFMIRegistrar._same_as_any`) are not within a cell of each
#: other.
_SAME_CENTRE_SQ = (1.0 + 1e-6) ** 2


@dataclass
class _Prepared:
    """What :meth:`IFMIRegistrar.candidates` needs of the reference (reused across calls).

    ``factor`` and ``rotation_factor`` are the pooling factors the reference's own extent
    asks for; a much larger moving map raises them for its call, and the pooled images,
    signatures and spectra of each factor are cached here.
    """

    shape: tuple[int, int]
    factor: int
    rotation_factor: int
    offset: tuple[int, int]  # (col0, row0) of the cropped reference in full cells
    crop: NDArray[np.uint8]  # occupied cells inside the bounding box, bits packed by row
    crop_width: int  # ... of this many columns
    distance: NDArray[np.float32] | None  # full-resolution distance map (refinement) ...
    distance_offset: tuple[int, int]  # ... of the cells from (col0, row0) on
    levels: dict[int, NDArray[np.float32]] = field(default_factory=dict)  # pooled images
    signatures: dict[int, NDArray[np.complex64]] = field(default_factory=dict)
    spectra: dict[tuple[int, int, int], NDArray[np.float32]] = field(default_factory=dict)
    memos: list[_Memo] = field(default_factory=list)  # the last moving maps (see _Memo)


@dataclass
class _Memo:
    """A moving map registered against a prepared reference, and what was found.

    The recursion may ask twice about the same remainder (a usual and a wider search, which
    differ only in how many rotation peaks they examine): the second call reuses the
    analysis of the moving map, the hypotheses of every angle already tried and their
    refinements. ``states`` is a copy, compared by content, so a changed map is never
    mistaken for the remembered one.
    """

    key: tuple[Any, ...]  # options that shape the hypotheses
    states: NDArray[np.int8] | _Cells
    moving: _Moving
    angle_correlation: NDArray[np.float64]
    hypotheses: dict[float, list[tuple[NDArray[np.float64], float]]] = field(default_factory=dict)
    refined: dict[bytes, tuple[NDArray[np.float64], int]] = field(default_factory=dict)


@dataclass(frozen=True)
class _Moving:
    factor: int
    rotation_factor: int
    coarse: NDArray[np.float32]
    for_rotation: NDArray[np.float32]
    offset: tuple[int, int]
    points: NDArray[np.float64]  # occupied cells (x, y), full resolution, subsampled


def _rot(theta: float) -> NDArray[np.float64]:
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _shift(tx: float, ty: float) -> NDArray[np.float64]:
    return np.array([[1.0, 0.0, tx], [0.0, 1.0, ty], [0.0, 0.0, 1.0]])


def _scale(s: float) -> NDArray[np.float64]:
    return np.array([[s, 0.0, 0.0], [0.0, s, 0.0], [0.0, 0.0, 1.0]])


def _draw_turned(
    image: NDArray[np.float32],
    theta: float,
    shift: NDArray[np.float64],
    canvas: NDArray[np.float32],
    maps: tuple[NDArray[np.float32], NDArray[np.float32]] | None = None,
) -> None:
    """Draw ``image`` turned by ``theta`` about the origin, then shifted by ``shift``, into
    ``canvas`` (bilinear, zero where no cell of ``image`` lands), in place. ``maps``: two
    float32 arrays of the canvas's shape to compute the map in (new ones if not given; a
    caller that draws many angles on one canvas gives them once).

    ``cv2.remap`` of the inverse map, computed here in numpy: every canvas cell is
    interpolated on its own, so the canvas has the same bits whatever the number of OpenCV
    threads. ``cv2.warpAffine`` does not guarantee that: its bilinear warp of a float image
    gave other bits on one thread than on two or more (canvases of about 200 cells and up),
    so a batch worker (one thread) and ``brokenness compute`` (then a thread per core) gave
    transforms that differed in their last digits, and could decide differently.
    """
    c, s = math.cos(theta), math.sin(theta)
    # canvas cell (u, v) shows image point R^T ((u, v) - shift): x = c du + s dv, y = -s du + c dv
    du = np.arange(canvas.shape[1], dtype=np.float64) - shift[0]
    dv = np.arange(canvas.shape[0], dtype=np.float64) - shift[1]
    if maps is None:
        maps = (np.empty(canvas.shape, np.float32), np.empty(canvas.shape, np.float32))
    map_x, map_y = maps
    np.add.outer((s * dv).astype(np.float32), (c * du).astype(np.float32), out=map_x)
    np.add.outer((c * dv).astype(np.float32), (-s * du).astype(np.float32), out=map_y)
    drawn = cv2.remap(
        image,
        map_x,
        map_y,
        cv2.INTER_LINEAR,
        dst=canvas,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=0.0,
    )
    if drawn is not canvas:  # a new image (OpenCV makes none for this type and size)
        canvas[...] = drawn


def _placement(points: NDArray[np.float64], matrix: NDArray[np.float64]) -> NDArray[np.float64]:
    """``points`` (N, 2) moved by the 3x3 ``matrix`` (the same expression every time, so a
    placement made again has the same bits)."""
    return points @ matrix[:2, :2].T + matrix[:2, 2]


def _local(ref: _Prepared, matrix: NDArray[np.float64]) -> NDArray[np.float64]:
    """``matrix`` (moving -> reference cells) into the frame of the reference's distance map."""
    col0, row0 = ref.distance_offset
    return _shift(-col0, -row0) @ matrix


def _refined_key(full: NDArray[np.float64], refine: bool) -> bytes:
    """Key of a hypothesis in :attr:`_Memo.refined`: its matrix, and whether it is refined."""
    return full.tobytes() + bytes([refine])


def _occupied_box(
    states: NDArray[np.int8], role: str, purpose: str
) -> tuple[NDArray[np.bool_], tuple[int, int, int, int]]:
    """The occupied cells of a 2D state grid and their bounding box ``(r0, r1, c0, c1)``.

    Raises
    ------
    MapError
        If the grid is not 2D or has no occupied cell.
    """
    if states.ndim != 2:
        raise MapError(f"{role} must be a 2D grid, got shape {states.shape}")
    occ = states == OCCUPIED
    box = _spectral.bounding_box(occ)
    if box is None:
        raise MapError(f"the {role} has no occupied cell, there is nothing {purpose}")
    return occ, box


def _window(
    cells: OccupiedCells, r0: int, r1: int, c0: int, c1: int, copy: bool = True
) -> NDArray[np.bool_]:
    """The occupied cells of rows ``r0:r1`` and columns ``c0:c1`` of the grid (contiguous;
    with ``copy=False`` a view of ``cells.crop`` when the window lies inside it)."""
    dc, dr = cells.offset
    h, w = cells.crop.shape
    if dr <= r0 and r1 <= dr + h and dc <= c0 and c1 <= dc + w:
        view = cells.crop[r0 - dr : r1 - dr, c0 - dc : c1 - dc]
        return view if not copy else np.ascontiguousarray(view)
    out = np.zeros((r1 - r0, c1 - c0), dtype=bool)
    a0, a1, b0, b1 = max(r0, dr), min(r1, dr + h), max(c0, dc), min(c1, dc + w)
    if a0 < a1 and b0 < b1:
        out[a0 - r0 : a1 - r0, b0 - c0 : b1 - c0] = cells.crop[a0 - dr : a1 - dr, b0 - dc : b1 - dc]
    return out


@dataclass(frozen=True, eq=False)
class _Cells:
    """What a memo keeps of :class:`OccupiedCells` to recognise them: the grid's and the
    crop's shapes, the offset, and the flat indices of the cells in the crop (a few bytes per
    cell, not a copy of the crop)."""

    shape: tuple[int, int]
    offset: tuple[int, int]
    crop_shape: tuple[int, ...]
    flat: NDArray[np.intp]

    @classmethod
    def of(cls, cells: OccupiedCells) -> _Cells:
        return cls(cells.shape, cells.offset, cells.crop.shape, cells.flat_indices())

    def same(self, cells: OccupiedCells) -> bool:
        if (self.shape, self.offset, self.crop_shape) != (
            cells.shape,
            cells.offset,
            cells.crop.shape,
        ):
            return False
        crop = cells.crop.reshape(-1)
        # as many cells, and all of them at the remembered places
        return self.flat.size == cells.count and bool(crop[self.flat].all())


def _coarse(
    crop: NDArray[np.bool_], cells: NDArray[np.int32] | None, factor: int
) -> NDArray[np.float32]:
    """The pooled image of ``crop`` (:func:`~brokenness.registration._spectral.
    coarse_indicator`), from its occupied ``cells`` when they are known."""
    if cells is None:
        return _spectral.coarse_indicator(crop, factor)
    return _spectral.coarse_indicator_of_points(cells, (crop.shape[0], crop.shape[1]), factor)


def _cells_box(cells: OccupiedCells) -> tuple[int, int, int, int] | None:
    """:func:`~brokenness.registration._spectral.bounding_box` of ``cells.crop``, from its
    ``points`` when they are given (listed row by row: the first and last rows are theirs)."""
    if cells.points is None:
        return _spectral.bounding_box(cells.crop)
    if cells.points.shape[0] == 0:
        return None
    x, y = cells.points[:, 0], cells.points[:, 1]
    return int(y[0]), int(y[-1]) + 1, int(x.min()), int(x.max()) + 1


def _crop_points(cells: OccupiedCells) -> NDArray[np.int32]:
    """``(x, y)`` of the occupied cells of ``cells.crop``, row by row (its ``points`` when
    given, else one scan of the crop)."""
    if cells.points is not None:
        return np.ascontiguousarray(cells.points, dtype=np.int32)
    found = cv2.findNonZero(np.ascontiguousarray(cells.crop, dtype=np.bool_).view(np.uint8))
    if found is None:
        return np.zeros((0, 2), dtype=np.int32)
    return np.asarray(found, dtype=np.int32).reshape(-1, 2)


def _same_moving(a: NDArray[np.int8] | _Cells, b: NDArray[np.int8] | OccupiedCells) -> bool:
    """Whether a remembered moving map and a new one (grids or occupied cells) are the same,
    by content."""
    if isinstance(a, _Cells):
        return isinstance(b, OccupiedCells) and a.same(b)
    if isinstance(b, OccupiedCells):
        return False
    return bool(np.array_equal(a, b))


def _check_int(name: str, value: Any, low: int, high: int) -> None:
    ok = isinstance(value, (int, np.integer)) and not isinstance(value, bool)
    if not (ok and low <= value <= high):
        raise ParameterError(f"ifmi: {name} must be an integer in [{low}, {high}], got {value!r}")


class IFMIRegistrar:
    """Improved Fourier-Mellin registration (see the module docstring for the method).

    Parameters
    ----------
    n_angles : int, default 360
        Angle bins over half a turn (0.5 degrees each before sub-bin refinement).
    n_radii : int, default 64
        Radius samples of the polar spectrum inside ``band``.
    band : (float, float), default (0.05, 0.8)
        Radii of the spectrum kept for the rotation, as fractions of the Nyquist frequency
        of the (reduced) image: ``0 <= low < high <= 1``.
    max_size : int, default 160
        The translation stage works on images of at most about this many cells per side;
        larger maps are max-pooled by an integer factor (chosen from the reference's occupied
        bounding box).
    rotation_size : int, default 384
        The same for the rotation stage, which costs one FFT per map and so affords a finer
        image (the angle is what the full-resolution refinement can least repair).
    rotation_peaks : int, default 2
        Angle-correlation peaks kept at most; each gives two hypotheses (``t`` and
        ``t + 180``).
    translation_peaks : int, default 1
        Translation-correlation peaks kept per rotation hypothesis (at least 3 cells apart):
        in repetitive buildings the true shift is not always the highest peak.
    rotation_whitening : float, default 0.5
        Exponent ``a`` of the normalisation of the angle cross-power spectrum,
        ``C / |C|^a``: 1 is the phase correlation of the paper (every angular frequency
        weighs the same), 0 the plain correlation of the signatures. A map made of parts
        turned by different angles gives one peak per part; below 1 the peaks keep the
        weight of the parts' structure, so the largest part's angle ranks higher (see
        ``rotation_peaks``).
    peak_ratio : float, default 0.5
        A peak after the highest is kept only if it reaches this fraction of the highest's
        height (0 keeps all ``rotation_peaks``). On our test maps a single correct rotation
        gives a runner-up of 0.1..0.2 of the top, a map with a symmetric layout up to 0.7;
        skipping the clear cases halves the time of a call.
    refine : bool, default True
        Polish each hypothesis at full resolution (Gauss-Newton on the distance map).
    refine_iterations : int, default 6
        Gauss-Newton steps of the refinement.
    max_points : int, default 1000
        Occupied moving cells used by the refinement and the ranking (evenly subsampled).
    agree_cells : float, default 1.5
        A moving cell agrees with the reference when it lies within this distance (cells)
        of an occupied reference cell (ranking of the hypotheses).
    workers : int, optional
        ``workers`` of :mod:`scipy.fft`, which computes the rotation stage's spectra (None:
        one thread). The translation stage uses OpenCV's DFT, whose threads
        ``cv2.setNumThreads`` sets.
    **unknown
        Rejected: any other keyword raises :class:`ParameterError` (so that a misspelt
        option of ``make_registrar("ifmi", ...)`` is a one-line error, not a ``TypeError``).

    Raises
    ------
    ParameterError
        If an option is out of range.
    """

    name = "ifmi"
    #: iFMI registers the occupied cells only (see the module docstring).
    uses_free_space = False
    #: ``candidates`` takes the moving map as :class:`~brokenness.registration.base.OccupiedCells`
    #: too (it only looks at the occupied cells).
    accepts_cells = True

    def __init__(
        self,
        *,
        n_angles: int = 360,
        n_radii: int = 64,
        band: tuple[float, float] = (0.05, 0.8),
        max_size: int = 160,
        rotation_size: int = 384,
        rotation_peaks: int = 2,
        translation_peaks: int = 1,
        rotation_whitening: float = 0.5,
        peak_ratio: float = 0.5,
        refine: bool = True,
        refine_iterations: int = 6,
        max_points: int = 1000,
        agree_cells: float = 1.5,
        workers: int | None = None,
        **unknown: Any,
    ) -> None:
        if unknown:
            names = ", ".join(sorted(unknown))
            raise ParameterError(f"ifmi: unknown option(s) {names}")
        _check_int("n_angles", n_angles, 16, 100_000)
        _check_int("n_radii", n_radii, 2, 10_000)
        try:
            low, high = (float(v) for v in band)
        except (TypeError, ValueError):
            raise ParameterError(
                f"ifmi: band must be two numbers (low, high), got {band!r}"
            ) from None
        if not 0.0 <= low < high <= 1.0:
            raise ParameterError(f"ifmi: band must satisfy 0 <= low < high <= 1, got {band!r}")
        _check_int("max_size", max_size, 32, 1_000_000)
        _check_int("rotation_size", rotation_size, 32, 1_000_000)
        _check_int("rotation_peaks", rotation_peaks, 1, 64)
        _check_int("translation_peaks", translation_peaks, 1, 16)
        ok = isinstance(rotation_whitening, (int, float)) and not isinstance(
            rotation_whitening, bool
        )
        if not (ok and 0.0 <= rotation_whitening <= 1.0):
            raise ParameterError(
                f"ifmi: rotation_whitening must be a number in [0, 1], got {rotation_whitening!r}"
            )
        ok = isinstance(peak_ratio, (int, float)) and not isinstance(peak_ratio, bool)
        if not (ok and 0.0 <= peak_ratio <= 1.0):
            raise ParameterError(f"ifmi: peak_ratio must be a number in [0, 1], got {peak_ratio!r}")
        if not isinstance(refine, bool):
            raise ParameterError(f"ifmi: refine must be True or False, got {refine!r}")
        _check_int("refine_iterations", refine_iterations, 1, 1000)
        _check_int("max_points", max_points, 10, 100_000_000)
        ok = isinstance(agree_cells, (int, float)) and not isinstance(agree_cells, bool)
        if not (ok and math.isfinite(agree_cells) and agree_cells > 0):
            raise ParameterError(
                f"ifmi: agree_cells must be a positive number, got {agree_cells!r}"
            )
        if workers is not None:
            _check_int("workers", workers, -1024, 1024)
        self.n_angles = int(n_angles)
        self.n_radii = int(n_radii)
        self.band = (low, high)
        self.max_size = int(max_size)
        self.rotation_size = int(rotation_size)
        self.rotation_peaks = int(rotation_peaks)
        self.translation_peaks = int(translation_peaks)
        self.rotation_whitening = float(rotation_whitening)
        self.peak_ratio = float(peak_ratio)
        self.refine = refine
        self.refine_iterations = int(refine_iterations)
        self.max_points = int(max_points)
        self.agree_cells = float(agree_cells)
        self.workers = None if workers is None else int(workers)

    def __repr__(self) -> str:
        return (
            f"IFMIRegistrar(n_angles={self.n_angles}, band={self.band}, max_size={self.max_size}, "
            f"rotation_peaks={self.rotation_peaks}, refine={self.refine})"
        )

    # -- cached helpers -----------------------------------------------------------------------
    def _signature(self, image: NDArray[np.float32]) -> NDArray[np.complex64]:
        size = scipy.fft.next_fast_len(max(image.shape), real=True)
        window = _spectral.hann_window(image.shape)
        grid = _spectral.polar_grid(size, self.n_angles, self.band, self.n_radii)
        return _spectral.log_polar_signature(image, window, size, grid, self.workers)

    # -- protocol -----------------------------------------------------------------------------
    def prepare_reference(self, reference_states: NDArray[np.int8] | OccupiedCells) -> _Prepared:
        """Crop, pool and transform the reference once (see :class:`IFMIRegistrar`).

        ``reference_states``: the reference's grid of cell states, or its occupied cells
        (:class:`~brokenness.registration.base.OccupiedCells`; the same preparation).

        Raises
        ------
        MapError
            If the reference is not 2D or has no occupied cell.
        """
        if isinstance(reference_states, OccupiedCells):
            cells = reference_states
        else:
            states = np.asarray(reference_states)
            occ, _ = _occupied_box(states, "reference", "to register to")
            cells = OccupiedCells(occ, (0, 0), (int(states.shape[0]), int(states.shape[1])))
        # the occupied cells, (x, y) in the crop row by row: the box, the outline and the
        # pooled images follow them, not the grid
        points = _crop_points(cells)
        if points.shape[0] == 0:
            raise MapError("the reference has no occupied cell, there is nothing to register to")
        dc, dr = cells.offset
        x, y = points[:, 0], points[:, 1]
        r0, r1 = int(y[0]) + dr, int(y[-1]) + 1 + dr
        c0, c1 = int(x.min()) + dc, int(x.max()) + 1 + dc
        h, w = cells.shape
        extent = max(r1 - r0, c1 - c0)
        factor = max(1, math.ceil(extent / self.max_size))
        rot_factor = max(1, math.ceil(extent / self.rotation_size))
        walls = _window(cells, r0, r1, c0, c1, copy=False)
        prepared = _Prepared(
            shape=(h, w),
            factor=factor,
            rotation_factor=rot_factor,
            offset=(c0, r0),
            crop=np.packbits(walls, axis=1),
            crop_width=c1 - c0,
            distance=None,
            distance_offset=(0, 0),
        )
        if self.refine:
            # The distance map is only read near the reference's walls (within the inlier
            # radius of the refinement), so it covers their bounding box and a margin: real
            # maps often have wide unknown borders.
            margin = max(_DISTANCE_MARGIN, 2 * factor + 8)
            dr0, dr1 = max(r0 - margin, 0), min(r1 + margin, h)
            dc0, dc1 = max(c0 - margin, 0), min(c1 + margin, w)
            # the outline found by looking up the cells' neighbours in the crop: off the
            # crop nothing is occupied, as off the window for _refine.edge_distance_field
            outline = _refine.edge_points(cells.crop, points)
            outline += np.array([dc - dc0, dr - dr0], dtype=np.int32)
            prepared.distance = _refine.outline_distance_field(outline, (dr1 - dr0, dc1 - dc0))
            prepared.distance_offset = (dc0, dr0)
        # the usual work, done up front (the pooled images from the cells)
        in_walls = points - np.array([c0 - dc, r0 - dr], dtype=np.int32)
        for f in (factor, rot_factor):
            prepared.levels[f] = _spectral.coarse_indicator_of_points(
                in_walls, (r1 - r0, c1 - c0), f
            )
        self._reference_signature(prepared, rot_factor)
        return prepared

    @staticmethod
    def _level(ref: _Prepared, factor: int) -> NDArray[np.float32]:
        """The reference's occupied indicator pooled by ``factor`` (cached)."""
        img = ref.levels.get(factor)
        if img is None:
            img = ref.levels[factor] = _spectral.coarse_indicator_packed(
                ref.crop, ref.crop_width, factor
            )
        return img

    def _reference_signature(self, ref: _Prepared, factor: int) -> NDArray[np.complex64]:
        sig = ref.signatures.get(factor)
        if sig is None:
            sig = ref.signatures[factor] = self._signature(self._level(ref, factor))
        return sig

    def _moving(self, moving: NDArray[np.int8] | OccupiedCells, ref: _Prepared) -> _Moving:
        cells: NDArray[np.int32] | None = None  # the occupied cells in the crop, if known
        if isinstance(moving, OccupiedCells):
            box = _cells_box(moving)
            if box is None:
                raise MapError("the moving map has no occupied cell, there is nothing to register")
            dc, dr = moving.offset
            r0, r1, c0, c1 = box[0] + dr, box[1] + dr, box[2] + dc, box[3] + dc
            crop = np.ascontiguousarray(moving.crop[box[0] : box[1], box[2] : box[3]])
            if moving.points is not None:
                cells = moving.points - np.array([box[2], box[0]], dtype=np.int32)
        else:
            occ, (r0, r1, c0, c1) = _occupied_box(np.asarray(moving), "moving map", "to register")
            crop = np.ascontiguousarray(occ[r0:r1, c0:c1])
        # a moving map much larger than the reference is pooled more (bounded FFT sizes)
        extent = max(r1 - r0, c1 - c0)
        factor = max(ref.factor, math.ceil(extent / self.max_size))
        rot_factor = max(ref.rotation_factor, math.ceil(extent / self.rotation_size))
        xy = _refine.edge_points(crop, cells)
        if xy.shape[0] > self.max_points:
            pick = np.linspace(0, xy.shape[0] - 1, self.max_points).round().astype(np.intp)
            xy = take_rows(xy, pick)
        points = xy.astype(np.float64) + np.array([c0, r0], dtype=np.float64)
        coarse = _coarse(crop, cells, factor)
        for_rotation = coarse if rot_factor == factor else _coarse(crop, cells, rot_factor)
        return _Moving(factor, rot_factor, coarse, for_rotation, (c0, r0), points)

    def _reference_spectrum(
        self, ref: _Prepared, factor: int, padded: tuple[int, int]
    ) -> NDArray[np.float32]:
        key = (factor, *padded)
        spec = ref.spectra.get(key)
        if spec is None:
            spec = _spectral.packed_spectrum(self._level(ref, factor), padded)
            if len(ref.spectra) >= _SPECTRA_CACHED:  # bounded: drop the oldest padding
                del ref.spectra[next(iter(ref.spectra))]
            ref.spectra[key] = spec
        return spec

    def _angle_correlation(self, ref: _Prepared, mov: _Moving) -> NDArray[np.float64]:
        """Phase correlation of the two log-polar signatures along the angle axis."""
        signature = self._reference_signature(ref, mov.rotation_factor)
        cross = signature * np.conj(self._signature(mov.for_rotation))
        cross = cross.sum(axis=0)
        corr = scipy.fft.irfft(_spectral.whiten(cross, self.rotation_whitening), n=self.n_angles)
        return np.asarray(corr, dtype=np.float64)

    def _rotations(self, corr: NDArray[np.float64]) -> list[float]:
        """Rotation hypotheses (radians, modulo pi), best angle-correlation peak first."""
        n = self.n_angles
        sep = max(2, n // 36)  # peaks at least 5 degrees apart
        out = []
        peaks = _spectral.circular_peaks(corr, self.rotation_peaks, sep)
        top = float(corr[peaks[0]])
        for i in peaks:
            if i != peaks[0] and not float(corr[i]) >= self.peak_ratio * top:
                continue  # a clear winner: weaker peaks are noise or the map's own symmetry
            off = _spectral.parabolic_offset(
                float(corr[(i - 1) % n]), float(corr[i]), float(corr[(i + 1) % n])
            )
            out.append((i + off) * math.pi / n)
        return out

    def _memo_key(self) -> tuple[Any, ...]:
        """The options a remembered analysis depends on (all but the peak selection)."""
        return (
            self.n_angles,
            self.rotation_whitening,
            self.n_radii,
            self.band,
            self.max_size,
            self.rotation_size,
            self.translation_peaks,
            self.refine,
            self.refine_iterations,
            self.max_points,
            self.agree_cells,
        )

    def _memo(self, ref: _Prepared, moving_states: NDArray[np.int8] | OccupiedCells) -> _Memo:
        """The analysis of ``moving_states`` against ``ref``, remembered for later calls.

        The last :data:`_MEMOS` moving maps are remembered: a step of the recursion asks for
        the hypotheses of what is left of the map with the usual and the wider search, which
        share the analysis, and the recovery registers two sets of suspect cells in turn.
        """
        states: NDArray[np.int8] | OccupiedCells
        if isinstance(moving_states, OccupiedCells):
            states = moving_states
        else:
            states = np.asarray(moving_states)
        key = self._memo_key()
        for memo in ref.memos:
            if memo.key == key and _same_moving(memo.states, states):
                return memo
        mov = self._moving(states, ref)
        kept = _Cells.of(states) if isinstance(states, OccupiedCells) else states.copy()
        memo = _Memo(key, kept, mov, self._angle_correlation(ref, mov))
        ref.memos.append(memo)
        del ref.memos[:-_MEMOS]
        return memo

    def candidates(
        self,
        prepared_reference: _Prepared,
        moving_states: NDArray[np.int8] | OccupiedCells,
        max_candidates: int,
    ) -> list[Candidate]:
        """Ranked hypotheses moving -> reference (best first, at least one).

        ``moving_states`` is the moving map's grid of cell states, or its occupied cells
        (:class:`~brokenness.registration.base.OccupiedCells`: the same hypotheses).

        Raises
        ------
        MapError
            If the moving map has no occupied cell.
        ParameterError
            If ``max_candidates < 1``.
        """
        if not isinstance(max_candidates, (int, np.integer)) or max_candidates < 1:
            raise ParameterError(
                f"max_candidates must be a positive integer, got {max_candidates!r}"
            )
        ref = prepared_reference
        memo = self._memo(ref, moving_states)
        mov = memo.moving
        f = mov.factor
        hyps = self._spectral_hypotheses(ref, memo)
        # coarse (cropped, pooled) frames -> full cells: X_full = f * X + (f - 1)/2 + offset
        half = 0.5 * (f - 1)
        to_ref = _shift(ref.offset[0] + half, ref.offset[1] + half) @ _scale(f)
        from_mov = _scale(1.0 / f) @ _shift(-mov.offset[0] - half, -mov.offset[1] - half)
        start = max(4.0, 2.0 * f + 2.0)  # error of the reduced-image estimate, cells
        fulls = [self._snap(to_ref @ matrix @ from_mov) for matrix, _ in hyps]
        counts = [0] * len(fulls)
        if ref.distance is not None:
            local = [_local(ref, full) for full in fulls]
            counts = _refine.inlier_counts(ref.distance, mov.points, local, start)
        prescreen = [(n0, z, full) for n0, (_, z), full in zip(counts, hyps, fulls, strict=True)]
        # hypotheses in order of promise: cells near a reference wall, then peak quality
        order = sorted(range(len(prescreen)), key=lambda k: (-prescreen[k][0], -prescreen[k][1], k))
        scored: list[tuple[int, float, int, NDArray[np.float64]]] = []
        # the centroids of the moving points under each kept hypothesis (the placements
        # themselves are made again where two centroids are close: one (N, 2) array at a
        # time, not one for each of the max_candidates); one a hypothesis at most, however
        # many are asked for
        centres = np.empty((min(max_candidates, len(order)), 2))
        best_n0 = prescreen[order[0]][0]
        if ref.distance is not None:  # the first promising ones, refined together
            promising = [prescreen[k][2] for k in order if 2 * prescreen[k][0] >= best_n0]
            self._refine_together(ref, memo, promising[:max_candidates], start)
        for k in order:
            n0, z, full = prescreen[k]
            score = 0
            if ref.distance is not None:
                # refine the hypotheses that are at least half as good near the walls as the
                # best one; the refinement only gains cells already near a wall, so the rest
                # are very unlikely to win and keep their spectral estimate (saves time)
                full, score = self._refined(ref, memo, full, start, 2 * n0 >= best_n0)
            moved = _placement(mov.points, full)
            centre = moved.mean(axis=0)
            kept = len(scored)
            if self._same_as_any(
                (moved, centre),
                centres[:kept],
                lambda i: _placement(mov.points, scored[i][3]),
            ):
                continue
            centres[kept] = centre
            scored.append((score, z, k, full))
            if len(scored) == max_candidates:
                break
        # best first: agreeing cells, then peak quality, then spectral order (deterministic)
        scored.sort(key=lambda item: (-item[0], -item[1], item[2]))
        return [
            Candidate(
                RigidTransform(math.atan2(full[1, 0], full[0, 0]), full[0, 2], full[1, 2]),
                self._confidence(z),
            )
            for _, z, _, full in scored
        ]

    def _refine_together(
        self, ref: _Prepared, memo: _Memo, hypotheses: list[NDArray[np.float64]], start: float
    ) -> None:
        """Refine ``hypotheses`` in one batch and remember them (see :meth:`_refined`)."""
        assert ref.distance is not None
        todo = [full for full in hypotheses if _refined_key(full, True) not in memo.refined]
        if not todo:
            return
        points = memo.moving.points
        local = [_local(ref, full) for full in todo]
        refined = _refine.refine_rigid_many(
            ref.distance,
            points,
            local,
            start_radius=start,
            end_radius=self.agree_cells,
            iterations=self.refine_iterations,
        )
        col0, row0 = ref.distance_offset
        scores = _refine.inlier_counts(ref.distance, points, local + refined, self.agree_cells)
        for i, (full, after_matrix) in enumerate(zip(todo, refined, strict=True)):
            score, after = scores[i], scores[len(todo) + i]
            out = full
            if after >= score:
                out, score = _shift(col0, row0) @ after_matrix, after
            memo.refined[_refined_key(full, True)] = (out, score)

    def _refined(
        self,
        ref: _Prepared,
        memo: _Memo,
        full: NDArray[np.float64],
        start: float,
        refine: bool,
    ) -> tuple[NDArray[np.float64], int]:
        """A hypothesis and its agreeing outline cells, refined if ``refine`` (remembered)."""
        key = _refined_key(full, refine)
        hit = memo.refined.get(key)
        if hit is not None:
            return hit
        assert ref.distance is not None
        if refine:
            self._refine_together(ref, memo, [full], start)
            return memo.refined[key]
        points = memo.moving.points
        score = _refine.inlier_count(ref.distance, points, _local(ref, full), self.agree_cells)
        memo.refined[key] = (full, score)
        return full, score

    # -- internals ----------------------------------------------------------------------------
    @staticmethod
    def _snap(matrix: NDArray[np.float64]) -> NDArray[np.float64]:
        """Re-orthonormalise the rotation part (float round-off of the compositions)."""
        theta = math.atan2(matrix[1, 0] - matrix[0, 1], matrix[0, 0] + matrix[1, 1])
        out = _rot(theta)
        out[:2, 2] = matrix[:2, 2]
        return out

    @staticmethod
    def _same_as_any(
        a: tuple[NDArray[np.float64], NDArray[np.float64]],
        centres: NDArray[np.float64],
        placement: Callable[[int], NDArray[np.float64]],
    ) -> bool:
        """Whether the placement ``a`` (N, 2) of the moving points lies within a cell of one
        of the earlier placements on average (mean distance of the points under 1).

        ``a`` comes with its centroid (shape (2,)); ``centres`` (K, 2) are the earlier
        placements' centroids and ``placement(i)`` makes the ``i``-th of them (N, 2). The
        mean distance of two placements is at least the distance of their centroids (the
        norm of the mean difference is at most the mean of the norms), so a placement whose
        centroid is more than ``1 + 1e-6`` from ``a``'s is not within a cell and is never
        made: the rounding of either mean is some 1e-12 of it, far below the margin. The
        others are compared in one pass: the squared distances as sums of two squares
        (:func:`~brokenness._points.squared_norms`) and each placement's mean a reduction
        of its own row, the same sums in the same order as comparing the pairs one at a
        time.
        """
        points, centre = a
        near = np.flatnonzero(squared_norms(centres - centre) <= _SAME_CENTRE_SQ)
        if near.size == 0:
            return False
        close = np.stack([placement(int(i)) for i in near])
        dist = np.sqrt(squared_norms(points - close))  # (K, N)
        return bool((np.mean(dist, axis=1) < 1.0).any())

    @staticmethod
    def _confidence(excess: float) -> float:
        """Peak quality mapped to [0, 1].

        ``excess`` is the z-score of the translation peak (height over the mean, in standard
        deviations of the correlation surface) minus the level that noise peaks reach,
        ``2.5 * sqrt(2 ln N)`` for a surface of ``N`` cells (about 12 here; unrelated maps
        gave peaks of z = 6..17 in our trials, true matches 25..250, partial ones 25..130).
        The confidence is ``1 - exp(-excess / 15)``: 0 at the noise level, 0.49 at z = 22,
        0.86 at z = 42.
        """
        return float(1.0 - math.exp(-max(0.0, excess) / 15.0))

    def _spectral_hypotheses(
        self, ref: _Prepared, memo: _Memo
    ) -> list[tuple[NDArray[np.float64], float]]:
        """(coarse-frame matrix moving -> reference, peak quality) for every hypothesis.

        The hypotheses of an angle already tried on the same moving map are remembered.
        """
        thetas = self._rotations(memo.angle_correlation)
        missing = [theta for theta in thetas if theta not in memo.hypotheses]
        if missing:
            memo.hypotheses.update(self._translations(ref, memo.moving, missing))
        return [h for theta in thetas for h in memo.hypotheses[theta]]

    def _translations(
        self, ref: _Prepared, mov: _Moving, thetas: list[float]
    ) -> dict[float, list[tuple[NDArray[np.float64], float]]]:
        """Per rotation ``theta`` (and its 180-degree twin), the translation hypotheses."""
        g = mov.coarse
        h, w = g.shape
        side = math.ceil(math.hypot(h, w)) + 2  # canvas holding the moving image at any angle
        coarse_ref = self._level(ref, mov.factor)
        hr, wr = coarse_ref.shape
        padded = (_spectral.packed_size(hr + side), _spectral.packed_size(wr + side))
        spec_ref = self._reference_spectrum(ref, mov.factor, padded)
        centre_m = np.array([(w - 1) / 2.0, (h - 1) / 2.0])
        centre_c = np.array([(side - 1) / 2.0, (side - 1) / 2.0])
        found: dict[float, list[tuple[NDArray[np.float64], float]]] = {}
        # one zero-padded canvas for every angle: each rotated image is drawn into its
        # corner (every cell of which the warp writes), the padding stays zero
        padded_canvas = np.zeros(padded, dtype=np.float32)
        canvas = padded_canvas[:side, :side]
        maps = (np.empty((side, side), np.float32), np.empty((side, side), np.float32))
        for theta in thetas:
            out: list[tuple[NDArray[np.float64], float]] = found.setdefault(theta, [])
            rot = _rot(theta)
            # moving -> canvas: rotate about the moving image centre into the canvas centre;
            # the shift is rounded so that theta = 0 is an exact (interpolation-free) copy
            t = np.round(centre_c - rot[:2, :2] @ centre_m)
            to_canvas = _shift(t[0], t[1]) @ rot
            _draw_turned(g, theta, t, canvas, maps)
            spec = _spectral.padded_spectrum(padded_canvas)
            for twin in (False, True):
                # the flipped canvas has the conjugate spectrum: correlate without conjugating
                cross = cv2.mulSpectrums(spec_ref, spec, 0, conjB=not twin)
                surface: NDArray[np.float32] = cv2.idft(  # type: ignore[assignment]
                    cross, flags=cv2.DFT_REAL_OUTPUT
                )
                for dy, dx, z in self._peaks(surface, self.translation_peaks):
                    if twin:
                        # flipped canvas g(-u): canvas point v lands on reference point d - v
                        matrix = _shift(dx, dy) @ _rot(math.pi) @ to_canvas
                    else:
                        # canvas point v lands on reference point v + d, d in (-side, size_ref)
                        if dy >= hr:
                            dy -= padded[0]
                        if dx >= wr:
                            dx -= padded[1]
                        matrix = _shift(dx, dy) @ to_canvas
                    out.append((matrix, z))
        return found

    @classmethod
    def _peaks(cls, surface: NDArray[np.floating], count: int) -> list[tuple[float, float, float]]:
        """The ``count`` highest peaks of a correlation surface, at least 3 cells apart.

        Repetitive buildings (rows of equal rooms, long corridors) give several peaks of
        similar height; the true one is not always the highest, so more than one translation
        per rotation can be handed on to be scored on the cells.

        The surface (a float32 temporary of the caller) is overwritten: each peak found is
        masked out in it before the next is looked for.
        """
        # statistics of the surface from a fixed subsample (speed), shared by its peaks
        # (numpy's sums: cv2.meanStdDev sums a large image on several threads, in an order
        # that depends on their number)
        sample = surface[::4, ::4]
        level = (float(np.mean(sample, dtype=np.float64)), float(np.std(sample, dtype=np.float64)))
        if count == 1:
            return [cls._peak(surface, level)]
        work = surface  # masked in place: no copy of the surface
        low = float(work.min())
        rows, cols = work.shape
        out = []
        for _ in range(count):
            r, c, z = cls._peak(work, level)
            out.append((r, c, z))
            ri, ci = int(round(r)) % rows, int(round(c)) % cols
            r0, c0 = ri - 3, ci - 3
            if 0 <= r0 and r0 + 7 <= rows and 0 <= c0 and c0 + 7 <= cols:
                work[r0 : r0 + 7, c0 : c0 + 7] = low
            else:  # the window wraps around an edge
                rr = np.arange(r0, r0 + 7) % rows
                cc = np.arange(c0, c0 + 7) % cols
                work[np.ix_(rr, cc)] = low
        return out

    @staticmethod
    def _peak(
        surface: NDArray[np.floating], level: tuple[float, float]
    ) -> tuple[float, float, float]:
        """Sub-cell ``(row, col)`` of the highest peak (index in [0, n)) and its quality.

        ``level`` is the mean and standard deviation of the surface; the quality is the
        peak's z-score minus the noise level (see :meth:`_confidence`).
        """
        rows, cols = surface.shape
        i = int(np.argmax(surface))
        r, c = divmod(i, cols)
        at = surface.item  # the cells as Python floats (exact), one lookup each
        v = at(r, c)
        oy = _spectral.parabolic_offset(at((r - 1) % rows, c), v, at((r + 1) % rows, c))
        ox = _spectral.parabolic_offset(at(r, (c - 1) % cols), v, at(r, (c + 1) % cols))
        mean, std = level
        z = (v - mean) / std if std > 0 else 0.0
        noise = 2.5 * math.sqrt(2.0 * math.log(surface.size))
        return r + oy, c + ox, z - noise
