"""Array kernels of the iFMI registration: images from cell states, spectra, peaks.

Pure functions on arrays; :mod:`brokenness.registration.ifmi` strings them together. All
images are float32, all spectra complex64 (half the memory of float64 and fast enough:
the peaks are refined to sub-bin precision and a final full-resolution refinement follows).

The translation stage, which runs once per rotation hypothesis, uses OpenCV's real DFT in
its packed ("CCS") layout: a real ``H x W`` image gives a real ``H x W`` spectrum holding
the ``W/2 + 1`` non-redundant columns, which ``cv2.mulSpectrums`` multiplies and
``cv2.idft`` inverts without unpacking. On the 2-core machine this is about twice as fast
as ``scipy.fft.rfft2`` / ``irfft2`` at the sizes used (300-400 cells per side), half of
that from not zero-padding through ``s=``. :func:`packed_size` keeps both sides even, the
layout :func:`whiten_packed` handles.
"""

from __future__ import annotations

import math
from functools import lru_cache

import cv2
import numpy as np
import scipy.fft
from numpy.typing import NDArray

__all__ = [
    "bounding_box",
    "circular_peaks",
    "coarse_indicator",
    "coarse_indicator_of_points",
    "coarse_indicator_packed",
    "hann_window",
    "log_polar_signature",
    "packed_size",
    "packed_spectrum",
    "padded_spectrum",
    "parabolic_offset",
    "polar_grid",
    "whiten",
    "whiten_packed",
]

F32 = NDArray[np.float32]


def bounding_box(mask: NDArray[np.bool_]) -> tuple[int, int, int, int] | None:
    """``(row0, row1, col0, col1)`` (half-open) of the True cells, or None if there are none."""
    rows = np.flatnonzero(mask.any(axis=1))
    if rows.size == 0:
        return None
    cols = np.flatnonzero(mask.any(axis=0))
    return int(rows[0]), int(rows[-1]) + 1, int(cols[0]), int(cols[-1]) + 1


def coarse_indicator(occupied: NDArray[np.bool_] | NDArray[np.uint8], factor: int) -> F32:
    """Occupied indicator (1.0 / 0.0), max-pooled by ``factor`` so that thin walls survive.

    Coarse cell ``(X, Y)`` covers the fine cells ``factor*X .. factor*X + factor - 1`` (the
    array is zero-padded up to a multiple of ``factor``), so its centre is the fine point
    ``factor*X + (factor - 1)/2``.
    """
    # a view of a larger grid is pooled as it is (no copy of the grid: the row blocks are
    # views of it too)
    img: NDArray[np.uint8] = (
        occupied.view(np.uint8) if occupied.dtype == np.bool_ else (occupied != 0).view(np.uint8)
    )
    if factor <= 1:
        return img.astype(np.float32)
    # max over row blocks, then (transposed, so the reduction is again over whole rows)
    # over column blocks: numpy reduces contiguous rows fast, short inner axes slowly
    img = _pool_rows(img, factor)
    img = _pool_rows(np.ascontiguousarray(img.T), factor)
    return np.ascontiguousarray(img.T, dtype=np.float32)


def coarse_indicator_of_points(
    points: NDArray[np.int32], shape: tuple[int, int], factor: int
) -> F32:
    """:func:`coarse_indicator` of a ``shape`` grid whose occupied cells are ``points``
    (``(x, y)``, distinct, all inside): each marks its coarse cell, so the cost follows the
    cells, not the grid."""
    rows, cols = shape
    f = max(int(factor), 1)
    out = np.zeros((-(-rows // f), -(-cols // f)), dtype=np.float32)
    if points.shape[0]:
        out[points[:, 1] // f, points[:, 0] // f] = 1.0
    return out


def coarse_indicator_packed(packed: NDArray[np.uint8], width: int, factor: int) -> F32:
    """:func:`coarse_indicator` of the cells packed by row in ``packed`` (``numpy.packbits``
    along axis 1 of a ``width``-column grid of booleans).

    The blocks of rows are pooled on the packed bytes (the maximum of 0/1 cells is their
    bitwise or, eight cells a byte), and only the pooled rows are unpacked: the same image,
    without a byte per cell of the grid.
    """
    if factor <= 1:
        return np.unpackbits(packed, axis=1, count=width).astype(np.float32)
    rows = _pool_rows(packed, factor, np.bitwise_or)
    img = np.unpackbits(rows, axis=1, count=width)
    img = _pool_rows(np.ascontiguousarray(img.T), factor)
    return np.ascontiguousarray(img.T, dtype=np.float32)


def _pool_rows(img: NDArray[np.uint8], factor: int, op: np.ufunc = np.maximum) -> NDArray[np.uint8]:
    """Max (or ``op``: the bitwise or of packed cells) over blocks of ``factor`` rows (a
    last, shorter block as it is: the zero rows that would pad it change no maximum of
    non-negative values)."""
    rows, cols = img.shape
    whole = rows // factor * factor
    out = op.reduce(img[:whole].reshape(rows // factor, factor, cols), axis=1)
    if whole < rows:
        out = np.concatenate([out, op.reduce(img[whole:], axis=0, keepdims=True)])
    return out


@lru_cache(maxsize=16)
def hann_window(shape: tuple[int, int]) -> F32:
    """Separable 2D Hann window (positive everywhere, so no row or column is lost).

    Memoised (a pure function of ``shape``; the array is read-only): every registration of
    maps of the same extent uses the same window.
    """
    rows, cols = shape
    wr = np.hanning(rows + 2)[1:-1].astype(np.float32)
    wc = np.hanning(cols + 2)[1:-1].astype(np.float32)
    window = np.outer(wr, wc)
    window.setflags(write=False)
    return window


@lru_cache(maxsize=16)
def polar_grid(
    size: int, n_angles: int, band: tuple[float, float], n_radii: int
) -> tuple[F32, F32]:
    """``cv2.remap`` maps that sample a half-plane (``rfft2``) spectrum on a polar grid.

    The spectrum is ``fftshift(rfft2(image, s=(size, size)), axes=0)``: column ``j`` holds
    the horizontal frequency ``j/size`` and row ``i`` the vertical one ``(i - size//2)/size``
    (cycles per cell). Output row ``k`` is the radius ``band`` (fractions of Nyquist = 0.5
    cycles/cell) linearly interpolated; output column ``a`` is the direction
    ``phi = -pi/2 + a*pi/n_angles`` of ``(fx, fy) = (x, y)`` frequency: the magnitude of a
    real image is point-symmetric, so half a turn covers every direction.

    Memoised like :func:`hann_window` (read-only arrays).
    """
    low, high = band
    radii = np.linspace(low * 0.5, high * 0.5, n_radii) * size
    phi = -0.5 * math.pi + np.arange(n_angles) * (math.pi / n_angles)
    map_x = (radii[:, None] * np.cos(phi)[None, :]).astype(np.float32)
    map_y = (radii[:, None] * np.sin(phi)[None, :] + size // 2).astype(np.float32)
    map_x.setflags(write=False)
    map_y.setflags(write=False)
    return map_x, map_y


def log_polar_signature(
    image: F32, window: F32, size: int, grid: tuple[F32, F32], workers: int | None
) -> NDArray[np.complex64]:
    """Angular spectrum of ``rfft2`` of the polar, band-filtered log magnitude.

    The image is windowed, zero-padded to ``size x size``, transformed; ``log1p`` of the
    magnitude is sampled on ``grid`` (rows = radii of the band, columns = angles); each
    radius row is made zero-mean and unit-variance (so that every radius of the band weighs
    the same and the isotropic part, which carries no angle, drops out), and transformed
    along the angle axis. Returns shape ``(n_radii, n_angles//2 + 1)``.
    """
    canvas = np.zeros((size, size), dtype=np.float32)  # padded here: faster than s=
    rows, cols = image.shape
    np.multiply(image, window, out=canvas[:rows, :cols])
    spec = scipy.fft.rfft2(canvas, workers=workers)
    mag = np.abs(spec).astype(np.float32, copy=False)
    np.log1p(mag, out=mag)
    mag = np.fft.fftshift(mag, axes=0)
    polar: F32 = np.asarray(
        cv2.remap(mag, grid[0], grid[1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE),
        dtype=np.float32,
    )
    polar -= polar.mean(axis=1, keepdims=True)
    polar /= polar.std(axis=1, keepdims=True) + np.float32(1e-6)
    return scipy.fft.rfft(polar, axis=1, workers=workers).astype(np.complex64)


def whiten(spectrum: NDArray[np.complex64], exponent: float = 1.0) -> NDArray[np.complex64]:
    """Phase-only spectrum ``F / |F|`` (zero where ``|F|`` is negligible).

    With ``exponent`` below 1, ``F / |F|^exponent``: a partial whitening that keeps some of
    the weight of the strong frequencies (0 leaves ``F`` as it is).

    Works in place (and returns its argument) when given a complex64 array: the spectra
    whitened here are temporaries.
    """
    out = spectrum if spectrum.dtype == np.complex64 else spectrum.astype(np.complex64)
    mag = np.abs(out)
    eps = np.float32(1e-6) * (float(mag.max()) if mag.size else 1.0) + np.float32(1e-30)
    np.maximum(mag, eps, out=mag)
    if exponent != 1.0:
        np.power(mag, np.float32(exponent), out=mag)
    np.reciprocal(mag, out=mag)
    out *= mag
    return out


def packed_size(n: int) -> int:
    """The smallest even length ``>= n`` that OpenCV's DFT transforms fast (2^a 3^b 5^c)."""
    m = cv2.getOptimalDFTSize(max(int(n), 2))
    while m % 2:
        m = cv2.getOptimalDFTSize(m + 1)
    return int(m)


def packed_spectrum(image: F32, shape: tuple[int, int]) -> F32:
    """Whitened DFT of ``image`` zero-padded to ``shape``, in OpenCV's packed layout.

    ``shape`` must be even on both sides (:func:`packed_size`) and hold the image. Two such
    spectra ``a``, ``b`` give the phase correlation ``cv2.idft(cv2.mulSpectrums(a, b, 0,
    conjB=True), flags=cv2.DFT_REAL_OUTPUT)`` (unnormalised: ``H * W`` times that of
    ``numpy.fft``).
    """
    rows, cols = image.shape
    canvas = np.zeros(shape, dtype=np.float32)
    canvas[:rows, :cols] = image
    return padded_spectrum(canvas)


def padded_spectrum(canvas: F32) -> F32:
    """:func:`packed_spectrum` of an image already zero-padded: ``canvas`` is the padded
    image itself (even sides), for a caller that draws its images into one padded canvas."""
    return whiten_packed(np.asarray(cv2.dft(canvas), dtype=np.float32))


def whiten_packed(spectrum: F32) -> F32:
    """:func:`whiten` for a spectrum in OpenCV's packed layout (even sides), in place.

    In that layout (``cv2.dft`` of a real ``H x W`` image) columns ``1 .. W-2`` hold the
    ``(real, imaginary)`` pairs of the horizontal frequencies ``1 .. W/2 - 1`` of every
    row; the first and last columns hold the horizontal frequencies 0 and ``W/2``, whose
    values along the rows are packed the same way (rows ``1 .. H-2`` in pairs, rows ``0``
    and ``H-1`` real).
    """
    h, w = spectrum.shape
    if h % 2 or w % 2 or h < 2 or w < 2:
        raise ValueError(f"packed spectra need even sides, got {h} x {w}")
    inner = spectrum[:, 1 : w - 1].view(np.complex64)  # (H, W/2 - 1) complex values
    sides = slice(0, w, w - 1)  # columns 0 and W-1
    re = spectrum[1 : h - 1 : 2, sides]  # (H/2 - 1, 2) pairs along the rows
    im = spectrum[2 : h - 1 : 2, sides]
    real = spectrum[0 : h : h - 1, sides]  # (2, 2) real values
    inner_mag = np.abs(inner)
    side_mag = np.sqrt(re * re + im * im)
    real_mag = np.abs(real)
    top = max(float(m.max(initial=0.0)) for m in (inner_mag, side_mag, real_mag))
    eps = np.float32(1e-6 * top + 1e-30)  # as in whiten: zero where |F| is negligible
    for mag in (inner_mag, side_mag, real_mag):
        np.maximum(mag, eps, out=mag)
        np.reciprocal(mag, out=mag)
    inner *= inner_mag
    spectrum[1 : h - 1 : 2, sides] = re * side_mag
    spectrum[2 : h - 1 : 2, sides] = im * side_mag
    spectrum[0 : h : h - 1, sides] = real * real_mag
    return spectrum


def parabolic_offset(left: float, centre: float, right: float) -> float:
    """Sub-bin position of a peak in (-0.5, 0.5) from three samples around it."""
    denom = left - 2.0 * centre + right
    if denom >= 0.0 or not math.isfinite(denom):
        return 0.0
    off = 0.5 * (left - right) / denom
    return float(min(0.5, max(-0.5, off)))


def circular_peaks(
    signal: NDArray[np.floating], count: int, min_separation: int, window: int = 1
) -> list[int]:
    """Indices of the ``count`` highest local maxima of a circular 1D signal.

    A local maximum is at least every value within ``window`` bins of it (circularly).
    Peaks closer than ``min_separation`` bins (circularly) to a higher one are skipped.
    Ties are broken by the lower index, so the result is deterministic.
    """
    s = np.asarray(signal, dtype=np.float64)
    n = s.size
    is_max = np.ones(n, dtype=bool)
    for k in range(1, window + 1):
        is_max &= (s >= np.roll(s, k)) & (s >= np.roll(s, -k))
    idx = np.flatnonzero(is_max)
    order = idx[np.lexsort((idx, -s[idx]))]
    chosen: list[int] = []
    for i in order:
        if all(min(abs(int(i) - j), n - abs(int(i) - j)) >= min_separation for j in chosen):
            chosen.append(int(i))
            if len(chosen) == count:
                break
    return chosen
