"""The overlay's raster: colours, and a small code image of what each pixel shows.

Everything here is numpy and OpenCV, without matplotlib, so that the fast per-pair picture
of a batch (:mod:`brokenness.report.fast_overlay`) and the publication figure
(:mod:`brokenness.report.overlay`) draw the same pixels with the same colours, and a batch
worker never imports matplotlib.

A display raster holds one small integer *code* per pixel, in drawing priority (a higher
code wins where several meet, and when a block of cells is pooled into one pixel): unknown,
free, a reference wall, an unassigned cell, then partition ``i`` as ``4 + i``. A large map
is pooled block by block (a block showing its most specific content), a small one enlarged;
the raster is built strip by strip, so its memory is a few bytes per *raster* pixel plus
strips of the maps, whatever their size. The first :data:`N_COLOURS` partitions get
distinct colours (colour-blind safe Okabe-Ito, then Tol's), later ones the same colours
striped with a dark shade.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from ..errors import MapError
from ..grid import OCCUPIED, UNKNOWN, OccupancyMap
from ..measure.result import UNASSIGNED, BrokennessResult
from ..transform import RigidTransform

__all__ = [
    "N_COLOURS",
    "PARTITION_COLOURS",
    "LegendEntry",
    "hex_rgb",
    "legend_entries",
    "legend_title",
    "overlay_image",
    "overlay_raster",
    "palette_rgb",
    "partition_colour",
    "partition_style",
    "reference_in_map_frame",
]

#: Okabe & Ito (2008) colour-blind safe palette without black, then a few more distinct hues.
PARTITION_COLOURS: tuple[str, ...] = (
    "#0072B2",  # blue
    "#E69F00",  # orange
    "#009E73",  # bluish green
    "#CC79A7",  # reddish purple
    "#D55E00",  # vermillion
    "#56B4E9",  # sky blue
    "#F0E442",  # yellow
    "#882255",  # wine (Tol)
    "#44AA99",  # teal (Tol)
    "#999933",  # olive (Tol)
    "#332288",  # indigo (Tol)
    "#CC6677",  # rose (Tol)
)
#: Partitions with a colour of their own; the next ones reuse the colours, striped.
N_COLOURS: int = len(PARTITION_COLOURS)
#: Colours of the reference's walls, free and unknown cells, and unassigned cells.
_REFERENCE_GREY = (0.62, 0.62, 0.62)
_FREE = (1.0, 1.0, 1.0)
_UNKNOWN = (0.91, 0.91, 0.91)
_UNASSIGNED = (0.0, 0.0, 0.0)


def partition_colour(index: int) -> str:
    """Colour of partition ``index`` (cycles after :data:`PARTITION_COLOURS`)."""
    return PARTITION_COLOURS[index % len(PARTITION_COLOURS)]


def partition_style(index: int) -> tuple[tuple[float, float, float], int]:
    """``(rgb, stripes)`` of partition ``index``: 0 plain, 1 or more striped."""
    return hex_rgb(partition_colour(index)), index // N_COLOURS


def _dark(rgb: Sequence[float]) -> tuple[float, float, float]:
    return (0.35 * rgb[0], 0.35 * rgb[1], 0.35 * rgb[2])


def hex_rgb(colour: str) -> tuple[float, float, float]:
    """``"#RRGGBB"`` as an (r, g, b) triple in [0, 1] (as ``matplotlib.colors.to_rgb``)."""
    h = colour.lstrip("#")
    return (int(h[0:2], 16) / 255, int(h[2:4], 16) / 255, int(h[4:6], 16) / 255)


def reference_in_map_frame(
    reference: OccupancyMap, transform: RigidTransform, shape: tuple[int, int]
) -> NDArray[np.bool_]:
    """Occupied cells of the reference drawn in the map's grid.

    ``transform`` maps map cells onto reference cells, so the value of map cell ``p`` is the
    reference at ``transform(p)`` (nearest neighbour).

    Parameters
    ----------
    reference : OccupancyMap
    transform : RigidTransform
        Map cells -> reference cells (the largest partition's transform).
    shape : (rows, cols)
        The map's shape.

    Returns
    -------
    ndarray of bool, shape ``shape``
    """
    rows, cols = shape
    src = reference.occupied.astype(np.uint8)
    warped = cv2.warpAffine(
        src,
        transform.matrix[:2].astype(np.float64),
        (cols, rows),
        flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=0,
    )
    return warped.astype(bool)


def overlay_image(
    result: BrokennessResult,
    map: OccupancyMap,
    reference: OccupancyMap,
    *,
    max_side: int | None = None,
) -> NDArray[np.float32]:
    """The overlay as an RGB float image in the map's grid, shape (rows, cols, 3).

    Parameters
    ----------
    result : BrokennessResult
        The result of :func:`brokenness.compute_brokenness` for ``map`` and ``reference``.
    map, reference : OccupancyMap
    max_side : int, optional
        Largest side of the image: a larger map is reduced by the smallest integer factor
        that fits, each block of cells showing its most telling cell (a partition, then an
        unassigned cell, a reference wall, free space, unknown), so that thin walls never
        vanish and the picture of a huge map costs little memory.

    Returns
    -------
    ndarray of float32 in [0, 1]
        Shape ``(ceil(rows / f), ceil(cols / f), 3)`` with ``f`` the reduction factor (1
        unless ``max_side`` asks for less).

    Raises
    ------
    MapError
        If the result's label image does not have the map's shape.
    """
    labels = np.asarray(result.labels)
    if labels.shape != map.shape:
        raise MapError(f"result labels have shape {labels.shape} but the map has shape {map.shape}")
    t0 = result.partitions[0].transform if result.partitions else RigidTransform.identity()
    n = len(result.partitions)
    # one small class per cell, by priority: 0 unknown < 1 free < 2 reference wall
    # < 3 unassigned < 4 + i partition i; one lookup table from class to colour
    dtype = np.uint8 if n < 250 else np.uint16
    classes = np.zeros(map.shape, dtype=dtype)
    classes[map.free] = 1
    classes[reference_in_map_frame(reference, t0, map.shape)] = 2
    classes[labels == UNASSIGNED] = 3
    assigned = labels >= 0
    classes[assigned] = labels[assigned].astype(dtype) + 4
    del assigned
    if max_side is not None and max(map.shape) > max_side:
        classes = _block_max(classes, -(-max(map.shape) // max(int(max_side), 1)))
    lut = np.array(
        [_UNKNOWN, _FREE, _REFERENCE_GREY, _UNASSIGNED]
        + [hex_rgb(partition_colour(i)) for i in range(n)],
        dtype=np.float32,
    )
    return lut[classes]


def _block_max(image: NDArray[np.integer], factor: int) -> NDArray[np.integer]:
    """Maximum over blocks of ``factor`` x ``factor`` cells (zero padding at the far edges)."""
    rows, cols = image.shape
    r, c = -(-rows // factor), -(-cols // factor)
    padded = np.zeros((r * factor, c * factor), dtype=image.dtype)
    padded[:rows, :cols] = image
    return padded.reshape(r, factor, c, factor).max(axis=(1, 3))


# -- the display raster -------------------------------------------------------------------------
#: Codes of the display raster, in drawing priority (a higher code wins a pooled pixel).
_C_UNKNOWN, _C_FREE, _C_REFERENCE, _C_UNASSIGNED, _C_PART0 = 0, 1, 2, 3, 4
#: Rows of a source grid handled at once (bounds the temporary memory of a large map).
_STRIP_ROWS = 512
#: Longest side of a display raster (a poster at 300 dpi).
_MAX_RASTER = 6000


@dataclass(frozen=True)
class _View:
    """A display raster over the box ``[x0, x0 + w * k) x [y0, y0 + h * k)`` of a grid.

    ``k`` source cells per raster pixel before enlarging by ``m`` (one of them is 1): a
    raster pixel is ``k / m`` cells wide.
    """

    x0: int
    y0: int
    k: int
    m: int
    w: int
    h: int

    @property
    def cells_per_pixel(self) -> float:
        return self.k / self.m

    def pixels(self, points: NDArray[np.float64]) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
        """Raster (column, row) of cell-coordinate points, -1 outside.

        The pixel of the block of ``k`` cells a point falls in; in an enlarged view
        (``m > 1``) the top-left pixel of its cell's ``m x m`` pixels, which
        :func:`_fill_cells` spreads right and down over the cell (so a cell's colour lands
        on the pixels of the background's same cell, not half a cell off).
        """
        u = np.floor((points[:, 0] + 0.5 - self.x0) / self.k).astype(np.intp) * self.m
        v = np.floor((points[:, 1] + 0.5 - self.y0) / self.k).astype(np.intp) * self.m
        outside = (u < 0) | (u >= self.w * self.m) | (v < 0) | (v >= self.h * self.m)
        u[outside] = -1
        v[outside] = -1
        return u, v

    def extent(self, grid: OccupancyMap, metres: bool) -> tuple[float, float, float, float]:
        """imshow extent (left, right, bottom, top) in cells, or metres (y up)."""
        x1, y1 = self.x0 + self.w * self.k, self.y0 + self.h * self.k
        if not metres or grid.resolution is None:
            return (self.x0 - 0.5, x1 - 0.5, y1 - 0.5, self.y0 - 0.5)
        r = grid.resolution
        ox, oy = (grid.origin or (0.0, 0.0, 0.0))[:2]
        rows = grid.shape[0]
        return (ox + self.x0 * r, ox + x1 * r, oy + (rows - y1) * r, oy + (rows - self.y0) * r)


def _view(box: tuple[int, int, int, int], target: int) -> _View:
    """A view of ``box = (x0, y0, x1, y1)`` whose raster's long side is about ``target``."""
    x0, y0, x1, y1 = box
    side = max(x1 - x0, y1 - y0, 1)
    target = max(16, min(int(target), _MAX_RASTER))
    if side >= target:
        k, m = -(-side // target), 1
    else:
        k, m = 1, max(1, target // side)
    w, h = -(-(x1 - x0) // k), -(-(y1 - y0) // k)
    return _View(x0, y0, k, m, max(w, 1), max(h, 1))


def _strips(rows: int) -> list[tuple[int, int]]:
    return [(r, min(r + _STRIP_ROWS, rows)) for r in range(0, rows, _STRIP_ROWS)]


def _known_box(grid: OccupancyMap, margin: float = 0.03) -> tuple[int, int, int, int]:
    """Bounding box (x0, y0, x1, y1) of the known cells, with a small margin."""
    rows, cols = grid.shape
    any_row = np.zeros(rows, bool)
    any_col = np.zeros(cols, bool)
    for a, b in _strips(rows):
        known = grid.states[a:b] != UNKNOWN
        any_row[a:b] = known.any(axis=1)
        any_col |= known.any(axis=0)
    if not any_row.any():
        return (0, 0, cols, rows)
    ys, xs = np.flatnonzero(any_row), np.flatnonzero(any_col)
    pad = int(round(margin * max(xs[-1] - xs[0] + 1, ys[-1] - ys[0] + 1))) + 2
    return (
        max(0, int(xs[0]) - pad),
        max(0, int(ys[0]) - pad),
        min(cols, int(xs[-1]) + 1 + pad),
        min(rows, int(ys[-1]) + 1 + pad),
    )


def _background(grid: OccupancyMap, view: _View) -> NDArray[np.uint16]:
    """Free (a block with any known cell) or unknown, pooled block by block.

    A strip of ``k`` source rows per raster row is pooled over its rows first (the maximum
    of ``k`` contiguous rows, an elementwise operation), then over the ``k`` columns of each
    block of the ``k`` times smaller result: the same maximum as over each block at once,
    at a fraction of the cost.
    """
    k = view.k
    rows, cols = grid.shape
    out = np.zeros((view.h, view.w), np.uint16)
    x0, x1 = view.x0, view.x0 + view.w * k
    cx0, cx1 = max(x0, 0), min(x1, cols)  # the columns of the box inside the grid
    step = max(1, _STRIP_ROWS // k)
    for v0 in range(0, view.h, step):
        v1 = min(view.h, v0 + step)
        a, b = view.y0 + v0 * k, view.y0 + v1 * k
        ca, cb = max(a, 0), min(b, rows)
        if ca >= cb or cx0 >= cx1:
            continue
        known = np.zeros((b - a, x1 - x0), np.uint8)  # 1 on a known cell, 0 elsewhere
        np.not_equal(
            grid.states[ca:cb, cx0:cx1],
            UNKNOWN,
            out=known[ca - a : cb - a, cx0 - x0 : cx1 - x0].view(np.bool_),
        )
        pooled_rows = known.reshape(v1 - v0, k, x1 - x0).max(axis=1)
        out[v0:v1] = pooled_rows.reshape(v1 - v0, view.w, k).max(axis=2)  # 1 free, 0 unknown
    return _enlarge(out, view.m)


def _enlarge(raster: NDArray[np.uint16], m: int) -> NDArray[np.uint16]:
    if m == 1:
        return raster
    return np.repeat(np.repeat(raster, m, axis=0), m, axis=1)


def _paint(
    raster: NDArray[np.uint16], view: _View, points: NDArray[np.float64], codes: NDArray[np.uint16]
) -> None:
    """Paint points with their codes; where several meet, the highest code wins."""
    u, v = view.pixels(points)
    inside = u >= 0
    u, v, codes = u[inside], v[inside], codes[inside]
    order = np.argsort(codes, kind="stable")  # the last write wins: highest code last
    raster[v[order], u[order]] = codes[order]


def _cells(mask: NDArray[np.bool_]) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """(rows, cols) of the True cells of a 2D mask, row by row (as :func:`numpy.nonzero`).

    OpenCV's scan of a mask of bytes is several times faster than numpy's on the large,
    sparse masks of a map's strips; the cells and their order are the same."""
    found = cv2.findNonZero(np.ascontiguousarray(mask).view(np.uint8))
    if found is None:
        empty = np.zeros(0, np.intp)
        return empty, empty.copy()
    xy = found.reshape(-1, 2)
    return xy[:, 1].astype(np.intp), xy[:, 0].astype(np.intp)


def _occupied_points(
    grid: OccupancyMap,
) -> list[tuple[NDArray[np.float64], NDArray[np.intp], NDArray[np.intp]]]:
    """Per strip: (points, rows, cols) of the occupied cells."""
    out = []
    for a, b in _strips(grid.shape[0]):
        rr, cc = _cells(grid.states[a:b] == OCCUPIED)
        rr = rr + a
        out.append((np.column_stack([cc, rr]).astype(np.float64), rr, cc))
    return out


def _cell_raster(view: _View) -> NDArray[np.uint16]:
    return np.zeros((view.h * view.m, view.w * view.m), np.uint16)


def _fill_cells(raster: NDArray[np.uint16], view: _View) -> NDArray[np.uint16]:
    """An enlarged view: every cell fills its m x m pixels (a max filter anchored top-left)."""
    if view.m == 1:
        return raster
    kernel = np.ones((view.m, view.m), np.uint8)
    anchor = (0, 0)
    # dilation with a kernel anchored at its top-left spreads a pixel right and down
    flipped = raster[::-1, ::-1]
    grown = cv2.dilate(flipped, kernel, anchor=anchor)
    return np.ascontiguousarray(grown[::-1, ::-1], dtype=np.uint16)


def _wall_radius(view: _View, pixels_per_raster_pixel: float, dpi: int) -> int:
    """Widening (pixels of the raster) that keeps one-cell walls visible."""
    cell_px = pixels_per_raster_pixel * view.m / view.k  # output pixels per cell
    if cell_px >= 3.0:
        return 0
    return 1 if dpi <= 200 else 2


def _widen(raster: NDArray[np.uint16], radius: int) -> NDArray[np.uint16]:
    if radius <= 0:
        return raster
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))
    return np.asarray(cv2.dilate(raster, kernel), dtype=np.uint16)


def _labelled_points(
    result: BrokennessResult, grid: OccupancyMap, moved: bool
) -> Iterator[tuple[NDArray[np.float64], NDArray[np.intp]]]:
    """Per strip of rows: the occupied cells' points and labels (moved: partitions only,
    each moved by its transform onto the reference)."""
    labels = np.asarray(result.labels)
    transforms = {p.index: p.transform for p in result.partitions}
    for a, b in _strips(grid.shape[0]):
        lab = labels[a:b]
        rr, cc = _cells((lab >= 0) | (lab == UNASSIGNED))
        if not len(rr):
            continue
        values = lab[rr, cc].astype(np.intp)
        points = np.column_stack([cc, rr + a]).astype(np.float64)
        if moved:
            keep = values >= 0
            points, values = points[keep], values[keep]
            for index in np.unique(values):
                sel = values == index
                points[sel] = transforms[int(index)].apply(points[sel])
        yield points, values


def _map_layer(
    result: BrokennessResult, grid: OccupancyMap, view: _View, moved: bool
) -> NDArray[np.uint16]:
    """The map's occupied cells coded by partition, in the view (moved: onto the reference)."""
    raster = _cell_raster(view)
    for points, values in _labelled_points(result, grid, moved):
        codes = np.where(values >= 0, values + _C_PART0, _C_UNASSIGNED).astype(np.uint16)
        _paint(raster, view, points, codes)
    return _fill_cells(raster, view)


def _reference_layer(
    reference: OccupancyMap, view: _View, to_view: RigidTransform | None
) -> NDArray[np.uint16]:
    """The reference's walls in the view (``to_view``: reference cells -> view cells)."""
    raster = _cell_raster(view)
    for points, _, _ in _occupied_points(reference):
        if not len(points):
            continue
        if to_view is not None:
            points = to_view.apply(points)
        _paint(raster, view, points, np.full(len(points), _C_REFERENCE, np.uint16))
    return _fill_cells(raster, view)


def _colours(n_parts: int) -> NDArray[np.float32]:
    """Code -> (plain rgb, stripe rgb), shape (codes, 2, 3)."""
    lut = np.zeros((_C_PART0 + max(n_parts, 1), 2, 3), np.float32)
    for code, rgb in (
        (_C_UNKNOWN, _UNKNOWN),
        (_C_FREE, _FREE),
        (_C_REFERENCE, _REFERENCE_GREY),
        (_C_UNASSIGNED, _UNASSIGNED),
    ):
        lut[code] = rgb
    for i in range(n_parts):
        rgb, stripes = partition_style(i)
        lut[_C_PART0 + i, 0] = rgb
        lut[_C_PART0 + i, 1] = _dark(rgb) if stripes else rgb
    return lut


def _colourize(codes: NDArray[np.uint16], n_parts: int, stripe: int) -> NDArray[np.float32]:
    """RGB image of a code raster; striped partitions alternate with a dark shade."""
    lut = _colours(n_parts)
    codes = np.minimum(codes, len(lut) - 1)
    h, w = codes.shape
    v, u = np.ogrid[:h, :w]
    phase = (((u + v) // max(1, stripe)) % 2).astype(np.intp)
    return lut[codes, phase]


def _compose(*layers: NDArray[np.uint16]) -> NDArray[np.uint16]:
    out = layers[0]
    for layer in layers[1:]:
        out = np.maximum(out, layer)
    return out


def _check(result: BrokennessResult, map: OccupancyMap) -> None:
    labels = np.asarray(result.labels)
    if labels.shape != map.shape:
        raise MapError(f"result labels have shape {labels.shape} but the map has shape {map.shape}")


def overlay_raster(
    result: BrokennessResult,
    map: OccupancyMap,
    reference: OccupancyMap,
    *,
    target: int = 1100,
    dpi: int = 150,
    panel: str = "overlay",
) -> tuple[NDArray[np.float32], _View]:
    """The RGB raster of one panel, about ``target`` pixels on its long side.

    ``panel``: ``"overlay"`` (map frame, reference behind), ``"map"`` (map frame, no
    reference) or ``"moved"`` (reference frame, each partition moved by its transform).
    Memory is a few bytes per *raster* pixel plus strips of the maps, whatever their size.
    """
    _check(result, map)
    if panel == "moved":
        view = _view(_moved_box(result, map, reference), target)
        back = _background(reference, view)
        ref_layer = _reference_layer(reference, view, None)
        map_layer = _map_layer(result, map, view, moved=True)
    else:
        view = _view(_known_box(map), target)
        back = _background(map, view)
        map_layer = _map_layer(result, map, view, moved=False)
        if panel == "overlay":
            t0 = result.partitions[0].transform if result.partitions else None
            to_map = t0.inverse() if t0 is not None else None
            ref_layer = _reference_layer(reference, view, to_map)
        else:
            ref_layer = np.zeros_like(map_layer)
    radius = _wall_radius(view, target / max(back.shape), dpi)
    codes = _compose(back, _widen(ref_layer, radius), _widen(map_layer, radius))
    stripe = max(2, 2 * radius + 2)
    return _colourize(codes, len(result.partitions), stripe), view


def _moved_box(
    result: BrokennessResult, map: OccupancyMap, reference: OccupancyMap
) -> tuple[int, int, int, int]:
    """Box of the reference's known cells and of the partitions' cells moved onto it."""
    x0, y0, x1, y1 = _known_box(reference)
    for pts, _ in _labelled_points(result, map, moved=True):
        if len(pts):
            x0, y0 = min(x0, int(pts[:, 0].min()) - 2), min(y0, int(pts[:, 1].min()) - 2)
            x1, y1 = max(x1, int(pts[:, 0].max()) + 3), max(y1, int(pts[:, 1].max()) + 3)
    rows, cols = reference.shape
    return (max(x0, -cols), max(y0, -rows), min(x1, 2 * cols), min(y1, 2 * rows))


# -- the legend's text --------------------------------------------------------------------------
def _turn(offset_deg: float) -> str:
    """How a partition is turned *in the map*, relative to P0, on screen, from its
    ``rotation_offset_deg``: that is the offset of its transform (map -> reference), the
    turn that undoes it, so the part itself is turned the other way (rows point down: a
    positive angle turns clockwise on screen)."""
    deg = -offset_deg
    if abs(deg) < 0.05:
        return "not turned"
    way = "clockwise" if deg > 0 else "counter-clockwise"
    return f"turned {abs(deg):.1f}\N{DEGREE SIGN} {way}"


@dataclass(frozen=True)
class LegendEntry:
    """One legend entry: its text and its swatch (colour, and stripes as partitions have)."""

    label: str
    rgb: tuple[float, float, float]
    stripes: int = 0


def legend_entries(
    result: BrokennessResult, map: OccupancyMap, moved: bool = False
) -> list[LegendEntry]:
    """The legend: per partition its size, turn and offset relative to P0; the unassigned
    cells (not in a ``moved`` panel); the reference."""
    entries: list[LegendEntry] = []
    metres = map.resolution is not None
    for p in result.partitions:
        label = f"P{p.index}: {p.cells} cells ({100.0 * p.fraction:.1f}%)"
        if p.index > 0:
            if metres and p.displacement_m is not None:
                disp = f"{p.displacement_m:.2f} m"
            else:
                disp = f"{p.displacement:.1f} cells"
            label += f", {_turn(p.rotation_offset_deg)}, off {disp}"
        rgb, stripes = partition_style(p.index)
        entries.append(LegendEntry(label, rgb, stripes))
    if result.unassigned_cells and not moved:
        share = 100.0 * result.unassigned_fraction
        entries.append(
            LegendEntry(f"unassigned: {result.unassigned_cells} cells ({share:.1f}%)", _UNASSIGNED)
        )
    entries.append(LegendEntry("reference", _REFERENCE_GREY))
    return entries


def legend_title(result: BrokennessResult) -> str:
    """The legend's title: the degree and the number of partitions."""
    n = len(result.partitions)
    return (
        f"degree {result.degree if result.measured else 'not measured'}, "
        f"{n} partition{'' if n == 1 else 's'} (turned/off: in the map, relative to P0, on screen)"
    )


def palette_rgb(n: int) -> Sequence[tuple[float, float, float]]:
    """RGB triples of the first ``n`` partition colours (for tests and other plots)."""
    return [hex_rgb(partition_colour(i)) for i in range(n)]
