"""The fast overlay: the per-pair picture of a batch, drawn with numpy and Pillow.

The same picture as :func:`brokenness.report.render_overlay`'s default layout, the same
raster and colours (:mod:`brokenness.report.raster`): the reference, brought into the map's
frame by the inverse of the largest partition's transform, in grey; every partition's
occupied cells in its colour (the first :data:`~brokenness.report.raster.N_COLOURS` plain,
later ones striped with a dark shade); unassigned cells in black; cropped to what the map
explored. Drawn at the map's own resolution, one pixel per cell, when the explored box fits
in ``max_side`` pixels (a larger map is pooled by the smallest integer factor that fits, a
block showing its most specific content, so that thin walls never vanish; a small map is
enlarged to ``min_side``), with a title and a text legend below it (per partition its size,
turn and offset relative to P0, as the figure's legend), and no axes.

Written as a palette PNG (one byte per pixel) without matplotlib: a few tens of
milliseconds for a map of 700 x 700 cells, against a few hundred for the figure, and a
memory of a few bytes per *picture* pixel plus strips of the maps, whatever their size.
"""

from __future__ import annotations

import io
import os
from typing import BinaryIO

import numpy as np
from numpy.typing import NDArray
from PIL import Image, ImageDraw, ImageFont

from .._atomic import atomic_write_bytes
from ..grid import OccupancyMap
from ..measure.result import BrokennessResult
from .raster import (
    _C_PART0,
    _background,
    _check,
    _colours,
    _compose,
    _known_box,
    _map_layer,
    _reference_layer,
    _view,
    _wall_radius,
    _widen,
    legend_entries,
    legend_title,
)

__all__ = ["FAST_MAX_SIDE", "FAST_MIN_SIDE", "fast_overlay_png", "render_fast_overlay"]

#: Longest side of the picture's map part, pixels (larger maps are pooled to fit).
FAST_MAX_SIDE: int = 1600
#: Shortest long side of the picture's map part, pixels (smaller maps are enlarged).
FAST_MIN_SIDE: int = 480
_MARGIN = 8
_WHITE = (255, 255, 255)
_BLACK = (0, 0, 0)


def _palette_image(
    codes: NDArray[np.uint16], n_parts: int, stripe: int
) -> tuple[NDArray[np.uint8], list[int], int]:
    """Index image, flat RGB palette, and the index of white in it (black follows).

    Index ``c`` is code ``c``'s plain colour, ``n + c`` its dark stripe shade (striped
    partitions alternate the two along diagonals ``stripe`` pixels wide, as the figure's).
    With too many partitions for a palette: an RGB image, an empty palette and -1.
    """
    lut = np.round(_colours(n_parts) * 255).astype(np.uint8)  # (codes, 2, 3)
    n = len(lut)
    codes = np.minimum(codes, n - 1)
    striped = np.zeros(n, bool)
    striped[_C_PART0:] = np.any(lut[_C_PART0:, 0] != lut[_C_PART0:, 1], axis=1)
    entries = np.concatenate([lut[:, 0], lut[:, 1]])
    white = 2 * n  # white and black are appended after the codes' 2n colours
    if 2 * n + 2 <= 256:
        index = codes.astype(np.uint8)
        if striped.any():
            h, w = codes.shape
            v, u = np.ogrid[:h, :w]
            dark = striped[codes] & ((((u + v) // stripe) % 2) == 1)
            index[dark] += np.uint8(n)
        palette = [int(x) for x in entries.reshape(-1)] + [*_WHITE, *_BLACK]
        return index, palette, white
    # too many partitions for a palette: an RGB image
    h, w = codes.shape
    v, u = np.ogrid[:h, :w]
    phase = (striped[codes] & ((((u + v) // stripe) % 2) == 1)).astype(np.intp)
    return lut[codes, phase], [], -1


def _font(size: int) -> ImageFont.FreeTypeFont | ImageFont.ImageFont:
    try:
        return ImageFont.load_default(size=size)
    except (TypeError, OSError):  # pragma: no cover - Pillow without FreeType
        return ImageFont.load_default()


def _draw_swatch(draw: ImageDraw.ImageDraw, box: tuple[int, int, int, int], fill, dark) -> None:
    draw.rectangle(box, fill=fill)
    if dark is None:
        return
    x0, y0, x1, y1 = box
    for d in range(0, 2 * (x1 - x0), 4):  # diagonal stripes, as the raster's
        draw.line([(x0 + d, y0), (x0, y0 + d)], fill=dark, width=2)
    draw.rectangle(box, outline=dark)


def fast_overlay_png(
    result: BrokennessResult,
    map: OccupancyMap,
    reference: OccupancyMap,
    *,
    title: str | None = None,
    max_side: int = FAST_MAX_SIDE,
    min_side: int = FAST_MIN_SIDE,
) -> bytes:
    """The overlay of a result as PNG bytes (numpy and Pillow, no matplotlib).

    Parameters
    ----------
    result : BrokennessResult
        The result of :func:`brokenness.compute_brokenness` for ``map`` and ``reference``.
    map, reference : OccupancyMap
        The two maps the result was computed from.
    title : str, optional
        Title line; by default the degree and the map's source.
    max_side : int
        Longest side of the map part of the picture: the explored box of a larger map is
        pooled by the smallest integer factor that fits (default :data:`FAST_MAX_SIDE`).
    min_side : int
        A smaller explored box is enlarged by an integer factor up to about this size.

    Returns
    -------
    bytes
        A PNG: the map part (one pixel per cell when it fits in ``max_side``) above a title
        and a text legend.

    Raises
    ------
    MapError
        If the result does not belong to the map (label image of another shape).
    """
    _check(result, map)
    box = _known_box(map)
    side = max(box[2] - box[0], box[3] - box[1], 1)
    view = _view(box, min(max(side, int(min_side)), int(max_side)))
    back = _background(map, view)
    map_layer = _map_layer(result, map, view, moved=False)
    t0 = result.partitions[0].transform if result.partitions else None
    ref_layer = _reference_layer(reference, view, t0.inverse() if t0 is not None else None)
    radius = _wall_radius(view, 1.0, dpi=100)  # walls a cell thin widened, as the figure's
    codes = _compose(back, _widen(ref_layer, radius), _widen(map_layer, radius))
    del back, map_layer, ref_layer
    n_parts = len(result.partitions)
    pixels, palette, white = _palette_image(codes, n_parts, max(2, 2 * radius + 2))
    h, w = codes.shape
    del codes

    if title is None:
        name = f" of {os.path.basename(map.source)}" if map.source else ""
        degree = result.degree if result.measured else "not measured"
        title = f"Degree of brokenness{name}: {degree}"
    entries = legend_entries(result, map)
    size = int(min(22, max(12, round(w / 55))))
    font, bold = _font(size), _font(size + 2)
    line = int(round(1.45 * size))
    probe = ImageDraw.Draw(Image.new("L", (1, 1)))
    texts = [(title, bold), (legend_title(result), font)] + [(e.label, font) for e in entries]
    widest = max(int(probe.textlength(t, font=f)) for t, f in texts)
    width = max(w, widest + 2 * line + 2 * _MARGIN)
    height = _MARGIN + line + 4 + h + _MARGIN + line * (1 + len(entries)) + _MARGIN

    if palette:
        canvas = Image.new("P", (width, height), white)
        canvas.putpalette(palette)
        ink: tuple[int, ...] | int = white + 1

        def colour(rgb: tuple[float, float, float]) -> int:
            # the partition colours are in the palette: index of the nearest entry
            target = np.round(np.asarray(rgb) * 255)
            pal = np.asarray(palette, float).reshape(-1, 3)
            return int(np.argmin(np.abs(pal - target).sum(axis=1)))
    else:
        canvas = Image.new("RGB", (width, height), _WHITE)
        ink = _BLACK

        def colour(rgb: tuple[float, float, float]) -> tuple[int, ...]:  # type: ignore[misc]
            return tuple(int(round(255 * c)) for c in rgb)

    top = _MARGIN + line + 4
    canvas.paste(Image.fromarray(pixels), ((width - w) // 2, top))
    del pixels
    draw = ImageDraw.Draw(canvas)
    draw.text((_MARGIN, _MARGIN), title, fill=ink, font=bold)
    y = top + h + _MARGIN
    draw.text((_MARGIN, y), legend_title(result), fill=ink, font=font)
    swatch = max(8, size - 2)
    for entry in entries:
        y += line
        sy = y + (line - swatch) // 2 - 2
        dark = (
            colour(tuple(0.35 * c for c in entry.rgb))  # type: ignore[arg-type]
            if entry.stripes
            else None
        )
        _draw_swatch(draw, (_MARGIN, sy, _MARGIN + swatch, sy + swatch), colour(entry.rgb), dark)
        draw.text((_MARGIN + swatch + size // 2, y), entry.label, fill=ink, font=font)
    buf = io.BytesIO()
    canvas.save(buf, format="PNG", compress_level=6)
    return buf.getvalue()


def render_fast_overlay(
    result: BrokennessResult,
    map: OccupancyMap,
    reference: OccupancyMap,
    path: str | os.PathLike[str] | BinaryIO,
    *,
    title: str | None = None,
    max_side: int = FAST_MAX_SIDE,
) -> None:
    """Write :func:`fast_overlay_png` to a file (atomically) or a binary file object.

    Parameters as for :func:`fast_overlay_png`; ``path`` gets a PNG whatever its suffix.
    """
    data = fast_overlay_png(result, map, reference, title=title, max_side=max_side)
    if isinstance(path, (str, os.PathLike)):
        atomic_write_bytes(path, data)
    else:
        path.write(data)
