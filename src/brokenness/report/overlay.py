"""The partition overlay: one picture that shows where a map is broken.

``mode="overlay"`` (the default) draws in the *map's* frame (cells as loaded, row 0 at the
top): the reference, brought into that frame by the inverse of the largest partition's
transform, in grey; every partition's occupied cells in its own colour; occupied cells that
belong to no partition in black. ``mode="split"`` draws two panels: the map coloured by
partition in its own frame, and each partition moved by its own transform onto the
reference (where every part lands; reference walls no part reaches stay grey). The legend
gives the degree and, per partition, its size, how it is turned in the map relative to the
largest partition (on screen, clockwise or counter-clockwise) and its displacement (metres
when the map has a resolution, cells otherwise).

Pictures that a paper can print, for maps up to 10000 x 10000 cells and beyond a dozen
partitions: the picture is cropped to what was explored, and drawn from a raster about the
size of the output picture (:mod:`brokenness.report.raster`: a large map is pooled, a block
showing its most specific content: a partition's wall wins over the reference, the
reference over free space; a small map is enlarged), never from a full-size colour image;
walls are then widened to stay visible whatever the map's size. The first
:data:`N_COLOURS` partitions get distinct colours (colour-blind safe Okabe-Ito, then
Tol's), later ones the same colours striped with a dark shade, and the legend swatches are
drawn the same way. Axes are in metres when the map has a resolution, in cells otherwise.

Only :class:`matplotlib.figure.Figure` with the Agg canvas is used, never ``pyplot``, so the
function works on a headless machine and leaves no global state behind. A batch draws its
per-pair pictures with :mod:`brokenness.report.fast_overlay` instead (numpy and Pillow, a
fraction of the time); this module is the publication figure.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import BinaryIO

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from .._atomic import atomic_path
from ..errors import MapError, ParameterError
from ..grid import OccupancyMap
from ..measure.result import BrokennessResult
from .raster import (
    N_COLOURS,
    PARTITION_COLOURS,
    _check,
    _dark,
    legend_entries,
    legend_title,
    overlay_image,
    overlay_raster,
    palette_rgb,
    partition_colour,
    partition_style,
    reference_in_map_frame,
)

__all__ = [
    "MODES",
    "N_COLOURS",
    "PARTITION_COLOURS",
    "overlay_figure",
    "overlay_image",
    "overlay_raster",
    "palette_rgb",
    "partition_colour",
    "partition_style",
    "reference_in_map_frame",
    "render_overlay",
]

#: Layouts of :func:`render_overlay`.
MODES: tuple[str, ...] = ("overlay", "split")


def _swatch(index: int) -> Patch:
    rgb, stripes = partition_style(index)
    if not stripes:
        return Patch(facecolor=rgb, edgecolor="none")
    return Patch(facecolor=rgb, edgecolor=_dark(rgb), hatch="////", linewidth=0.0)


def _legend_handles(
    result: BrokennessResult, map: OccupancyMap, moved: bool = False
) -> list[Patch]:
    handles: list[Patch] = []
    entries = legend_entries(result, map, moved)
    for p, entry in zip(result.partitions, entries, strict=False):
        patch = _swatch(p.index)
        patch.set_label(entry.label)
        handles.append(patch)
    for entry in entries[len(result.partitions) :]:
        handles.append(Patch(facecolor=entry.rgb, edgecolor="none", label=entry.label))
    return handles


def _axes_labels(ax: Axes, grid: OccupancyMap, frame: str) -> None:
    if grid.resolution is not None:
        ax.set_xlabel(f"x (m, {frame} frame)")
        ax.set_ylabel(f"y (m, {frame} frame)")
    else:
        ax.set_xlabel(f"column ({frame} cells)")
        ax.set_ylabel(f"row ({frame} cells)")


def overlay_figure(
    result: BrokennessResult,
    map: OccupancyMap,
    reference: OccupancyMap,
    *,
    title: str | None = None,
    width_inches: float = 8.0,
    dpi: int = 150,
    mode: str = "overlay",
) -> Figure:
    """The partition overlay as a :class:`matplotlib.figure.Figure` (Agg canvas).

    The legend sits below the map, outside it, in space that the constrained layout
    reserves, so that no entry is clipped whatever the map's aspect ratio or the length of
    the entries. Parameters as for :func:`render_overlay`.

    Returns
    -------
    matplotlib.figure.Figure
    """
    if mode not in MODES:
        raise ParameterError(f"overlay mode must be one of {', '.join(MODES)}, got {mode!r}")
    if dpi <= 0 or width_inches <= 0:
        raise MapError("dpi and width must be positive")
    _check(result, map)
    panels = ["overlay"] if mode == "overlay" else ["map", "moved"]
    target = int(width_inches * dpi * (0.85 if mode == "overlay" else 0.45))
    rasters = [
        overlay_raster(result, map, reference, target=target, dpi=dpi, panel=p) for p in panels
    ]
    handles = _legend_handles(result, map)
    ncols = 1 if len(handles) <= 3 else 2
    legend_rows = -(-len(handles) // ncols)
    aspect = max(r.shape[0] / r.shape[1] for r, _ in rasters)
    panel_width = width_inches * (0.9 if mode == "overlay" else 0.45)
    image_height = min(max(panel_width * aspect, 1.5), 1.6 * width_inches)
    height = image_height + 0.9 + 0.2 * (legend_rows + 1)
    fig = Figure(figsize=(width_inches, height), dpi=dpi, layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, len(panels), squeeze=False)[0]
    for ax, panel, (rgb, view) in zip(axes, panels, rasters, strict=True):
        grid = reference if panel == "moved" else map
        metres = grid.resolution is not None
        ax.imshow(  # the raster is about the picture's size: nearest is exact enough, fast
            np.round(rgb * 255).astype(np.uint8),
            interpolation="nearest",
            origin="upper",
            extent=view.extent(grid, metres),
        )
        _axes_labels(ax, grid, "reference" if panel == "moved" else "map")
        if panel == "map":
            ax.set_title("the map, coloured by partition", fontsize="medium")
        elif panel == "moved":
            ax.set_title("each partition moved onto the reference", fontsize="medium")
    if title is None:
        name = f" of {os.path.basename(map.source)}" if map.source else ""
        degree = result.degree if result.measured else "not measured"
        title = f"Degree of brokenness{name}: {degree}"
    fig.suptitle(title)
    fig.legend(
        handles=handles,
        title=legend_title(result),
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
    mode: str = "overlay",
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
    mode : {"overlay", "split"}
        One panel (the partitions over the reference, in the map's frame) or two (the map
        coloured by partition in its own frame; each partition moved onto the reference).

    Raises
    ------
    MapError
        If the result does not belong to the map (label image of another shape).
    ParameterError
        For an unknown ``mode``.
    OSError
        If the file cannot be written (the file is replaced only once the picture is
        written whole).

    Examples
    --------
    >>> render_overlay(result, m, ref, "overlay.png", dpi=300)  # doctest: +SKIP
    """
    fig = overlay_figure(
        result, map, reference, title=title, width_inches=width_inches, dpi=dpi, mode=mode
    )
    # "tight" on top of the constrained layout: the saved picture holds every artist (the
    # layout alone can miss a few pixels of the title when the image's aspect is fixed)
    if isinstance(path, (str, os.PathLike)):
        # atomic: a temporary file beside it replaces it once written (its format named,
        # as the temporary name has no suffix to tell it; a path without one gets a PNG)
        kind = Path(path).suffix.lower().lstrip(".") or "png"
        with atomic_path(path) as tmp:
            fig.savefig(os.fspath(tmp), dpi=dpi, format=kind, bbox_inches="tight", pad_inches=0.08)
    else:
        fig.savefig(
            path,
            dpi=dpi,
            format="png",
            metadata={"Software": None},
            bbox_inches="tight",
            pad_inches=0.08,
        )
