"""The partition overlay: one picture that shows where a map is broken.

The picture is drawn in the *map's* frame (cells as loaded, row 0 at the top): the reference,
brought into that frame by the inverse of the largest partition's transform, in light grey;
every partition's occupied cells in its own colour (the colour-blind safe Okabe-Ito palette);
occupied cells that belong to no partition in black. The legend gives the degree and, per
partition, its size, rotation offset and displacement relative to the largest partition.

Only :class:`matplotlib.figure.Figure` with the Agg canvas is used, never ``pyplot``, so the
function works on a headless machine and leaves no global state behind.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import BinaryIO

import cv2
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import to_rgb
from matplotlib.figure import Figure
from matplotlib.patches import Patch
from numpy.typing import NDArray

from ..errors import MapError
from ..grid import OccupancyMap
from ..measure.result import UNASSIGNED, BrokennessResult
from ..transform import RigidTransform

__all__ = [
    "PARTITION_COLOURS",
    "overlay_figure",
    "overlay_image",
    "palette_rgb",
    "partition_colour",
    "reference_in_map_frame",
    "render_overlay",
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
)
_REFERENCE_GREY = (0.62, 0.62, 0.62)
_FREE = (1.0, 1.0, 1.0)
_UNKNOWN = (0.91, 0.91, 0.91)
_UNASSIGNED = (0.0, 0.0, 0.0)


def partition_colour(index: int) -> str:
    """Colour of partition ``index`` (cycles after :data:`PARTITION_COLOURS`)."""
    return PARTITION_COLOURS[index % len(PARTITION_COLOURS)]


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
        + [to_rgb(partition_colour(i)) for i in range(n)],
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


def _legend_handles(result: BrokennessResult) -> list[Patch]:
    handles: list[Patch] = []
    for p in result.partitions:
        label = f"P{p.index}: {p.cells} cells ({100.0 * p.fraction:.1f}%)"
        if p.index > 0:
            disp = (
                f"{p.displacement_m:.2f} m"
                if p.displacement_m is not None
                else f"{p.displacement:.1f} cells"
            )
            label += f", rot {p.rotation_offset_deg:+.1f}\N{DEGREE SIGN}, off {disp}"
        handles.append(Patch(facecolor=partition_colour(p.index), edgecolor="none", label=label))
    if result.unassigned_cells:
        share = 100.0 * result.unassigned_fraction
        handles.append(
            Patch(
                facecolor=_UNASSIGNED,
                edgecolor="none",
                label=f"unassigned: {result.unassigned_cells} cells ({share:.1f}%)",
            )
        )
    handles.append(Patch(facecolor=_REFERENCE_GREY, edgecolor="none", label="reference"))
    return handles


def overlay_figure(
    result: BrokennessResult,
    map: OccupancyMap,
    reference: OccupancyMap,
    *,
    title: str | None = None,
    width_inches: float = 8.0,
    dpi: int = 150,
) -> Figure:
    """The partition overlay as a :class:`matplotlib.figure.Figure` (Agg canvas).

    The legend sits below the map, outside it, in space that the constrained layout
    reserves, so that no entry is clipped whatever the map's aspect ratio or the length of
    the entries. Parameters as for :func:`render_overlay`.

    Returns
    -------
    matplotlib.figure.Figure
    """
    if dpi <= 0 or width_inches <= 0:
        raise MapError("dpi and width must be positive")
    # at most about two image pixels per picture pixel: a huge map is reduced (walls kept)
    # before matplotlib, which would otherwise resample it in float64 RGBA at full size
    rgb = overlay_image(result, map, reference, max_side=max(int(2 * width_inches * dpi), 1024))
    rows, cols = map.shape
    handles = _legend_handles(result)
    ncols = 1 if len(handles) <= 3 else 2
    legend_rows = -(-len(handles) // ncols)
    # the map gets about the full width; its height follows the aspect ratio (within limits)
    image_height = min(max(width_inches * 0.9 * rows / cols, 1.5), 1.6 * width_inches)
    height = image_height + 0.75 + 0.2 * (legend_rows + 1)
    fig = Figure(figsize=(width_inches, height), dpi=dpi, layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    # "nearest" when a cell covers several pixels, smoothing only when cells are smaller
    ax.imshow(
        rgb,
        interpolation="antialiased",
        interpolation_stage="rgba",
        origin="upper",
        extent=(-0.5, cols - 0.5, rows - 0.5, -0.5),  # axes in map cells, even when reduced
    )
    ax.set_xlabel("column (cells)")
    ax.set_ylabel("row (cells)")
    if title is None:
        name = f" of {os.path.basename(map.source)}" if map.source else ""
        title = f"Degree of brokenness{name}: {result.degree}"
    ax.set_title(title)
    fig.legend(
        handles=handles,
        title=f"degree {result.degree}, {len(result.partitions)} partition(s)",
        loc="outside lower center",
        ncols=ncols,
        fontsize="small",
        title_fontsize="small",
        frameon=False,
        handlelength=1.5,
        columnspacing=1.5,
    )
    return fig


def render_overlay(
    result: BrokennessResult,
    map: OccupancyMap,
    reference: OccupancyMap,
    path: str | os.PathLike[str] | BinaryIO,
    *,
    dpi: int = 150,
    title: str | None = None,
    width_inches: float = 8.0,
) -> None:
    """Write the partition overlay of a result as a PNG file.

    Parameters
    ----------
    result : BrokennessResult
        The result of :func:`brokenness.compute_brokenness` for ``map`` and ``reference``.
    map, reference : OccupancyMap
        The two maps the result was computed from.
    path : path-like or binary file
        Output file; the format follows the suffix (``.png`` recommended, ``.pdf``/``.svg``
        also work). A file object gets a PNG.
    dpi : int
        Resolution of the picture (150 for screens, 300 for print).
    title : str, optional
        Title; by default the degree and the map's source.
    width_inches : float
        Width of the figure before it is trimmed to its content (the legend is below the
        map); the saved picture is about this wide.

    Raises
    ------
    MapError
        If the result does not belong to the map (label image of another shape).
    OSError
        If the file cannot be written.

    Examples
    --------
    >>> render_overlay(result, m, ref, "overlay.png", dpi=300)  # doctest: +SKIP
    """
    fig = overlay_figure(result, map, reference, title=title, width_inches=width_inches, dpi=dpi)
    # "tight" on top of the constrained layout: the saved picture holds every artist (the
    # layout alone can miss a few pixels of the title when the image's aspect is fixed)
    if isinstance(path, (str, os.PathLike)):
        fig.savefig(os.fspath(path), dpi=dpi, bbox_inches="tight", pad_inches=0.08)
    else:
        fig.savefig(
            path,
            dpi=dpi,
            format="png",
            metadata={"Software": None},
            bbox_inches="tight",
            pad_inches=0.08,
        )


def palette_rgb(n: int) -> Sequence[tuple[float, float, float]]:
    """RGB triples of the first ``n`` partition colours (for tests and other plots)."""
    return [to_rgb(partition_colour(i)) for i in range(n)]
