"""Result files: one self-contained zip per evaluated map, readable without the inputs.

Like the result files of ``evo``, a record can be compared and plotted later
(``brokenness compare``) long after the maps are gone. Members of the zip:

``info.json``
    Package version, method, parameters, input paths with their SHA-256 checksums, timings,
    creation date and any extra information of the caller (labels of a batch run...).
``stats.json``
    Deterministic figures: :meth:`BrokennessResult.to_dict` plus, per partition, the
    transform in cells and metres, translation norms and the transform relative to the
    largest partition; the unassigned cells; Psi of the map and of the repaired map against
    the reference; shapes and geometry of both maps.
``labels.npy``
    The partition label image (the map's grid; -1 not occupied, -2 unassigned): int8 when
    the labels fit (fewer than 128 partitions), int16 otherwise; read back as int16.
``overlay.png``
    The partition overlay: the publication figure (:func:`brokenness.report.render_overlay`,
    ``overlay="figure"``, the default), or the fast raster picture a batch draws
    (:func:`brokenness.report.fast_overlay.fast_overlay_png`, ``overlay="fast"``); absent
    with ``overlay="none"`` (``info.json`` says which, as ``"overlay"``).

Writes are atomic: the zip is written to a temporary file in the destination folder and
renamed over the destination with :func:`os.replace` only when complete, so an exception, a
crash or Ctrl-C never leaves a half-written file behind.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import io
import json
import math
import os
import reprlib
import zipfile
from collections.abc import Callable, Mapping
from concurrent.futures import ThreadPoolExecutor
from contextlib import nullcontext
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .. import __version__
from .._atomic import atomic_path, sync_file
from .._atomic import atomic_write_bytes as atomic_write
from ..errors import BrokennessError, ParameterError
from ..grid import OccupancyMap
from ..limits import max_cells, max_file_bytes
from ..measure.result import BrokennessResult
from ..transform import RigidTransform
from .repair import Repair, repair

__all__ = [
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "OVERLAY_KINDS",
    "ResultFileError",
    "ResultRecord",
    "atomic_write",
    "build_stats",
    "file_sha256",
    "load_results",
    "parse_json",
    "save_results",
]

FORMAT_NAME = "brokenness-results"
FORMAT_VERSION = 1
_MEMBERS = ("info.json", "stats.json", "labels.npy", "overlay.png")
#: Members every result file has (``overlay.png`` is absent when no overlay was asked for).
_REQUIRED = _MEMBERS[:3]
#: What ``overlay.png`` of a result file is: the matplotlib figure, the fast raster picture,
#: or none at all.
OVERLAY_KINDS: tuple[str, ...] = ("figure", "fast", "none")
_ZIP_DATE = (1980, 1, 1, 0, 0, 0)  # fixed member dates: same content -> same bytes


class ResultFileError(BrokennessError, ValueError):
    """A result file is missing, not a zip, or lacks one of its members."""


@dataclass(frozen=True, eq=False)
class ResultRecord:
    """A result file as read back by :func:`load_results` (no inputs needed).

    Attributes
    ----------
    info : dict
        Content of ``info.json`` (version, parameters, inputs, timings, labels...).
    stats : dict
        Content of ``stats.json`` (degree, partitions, Psi...).
    labels : ndarray of int16
        The partition label image in the map's grid.
    overlay_png : bytes
        The overlay picture (empty when the file has none).
    path : Path or None
        Where the record was read from or written to.
    """

    info: dict[str, Any]
    stats: dict[str, Any]
    labels: NDArray[np.int16]
    overlay_png: bytes
    path: Path | None = None

    @property
    def measured(self) -> bool:
        """Whether the degree was measured (results written before this field: True)."""
        return bool(self.stats.get("measured", True)) and self.stats.get("degree") is not None

    @property
    def degree(self) -> int | None:
        """Degree of brokenness, ``None`` when it was not measured."""
        return int(self.stats["degree"]) if self.measured else None

    @property
    def run_labels(self) -> dict[str, str]:
        """Labels of the run (system, dataset, noise...), empty when none were given."""
        return dict(self.info.get("labels") or {})


# -- helpers ----------------------------------------------------------------------------------
def file_sha256(path: str | os.PathLike[str]) -> str | None:
    """SHA-256 hex digest of a file, or ``None`` when ``path`` is not a regular file."""
    p = Path(path)
    if not p.is_file():
        return None
    digest = hashlib.sha256()
    with p.open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _jsonable(value: Any) -> Any:
    """Plain JSON types; non-finite floats become ``None``, unknown objects their ``str``."""
    if isinstance(value, Mapping):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return _jsonable(value.tolist())
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        f = float(value)
        return f if math.isfinite(f) else None
    if value is None or isinstance(value, str):
        return value
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    return str(value)


def _dumps(obj: Any) -> bytes:
    return (json.dumps(_jsonable(obj), indent=2, sort_keys=True, allow_nan=False) + "\n").encode()


def _geometry(m: OccupancyMap) -> dict[str, Any]:
    rows, cols = m.shape
    return {
        "rows": rows,
        "cols": cols,
        "resolution": m.resolution,
        "origin": list(m.origin) if m.origin is not None else None,
        "occupied_cells": m.n_occupied,
    }


def _transform_figures(t: RigidTransform, resolution: float | None) -> dict[str, Any]:
    out: dict[str, Any] = dict(t.to_dict())
    out["translation_norm_cells"] = math.hypot(t.tx, t.ty)
    if t.world is not None:
        out["translation_norm_m"] = math.hypot(t.world.tx, t.world.ty)
    elif resolution is not None:
        out["translation_norm_m"] = math.hypot(t.tx, t.ty) * resolution
    else:
        out["translation_norm_m"] = None
    return out


def build_stats(
    result: BrokennessResult,
    map: OccupancyMap,
    reference: OccupancyMap,
    rep: Repair | None = None,
) -> dict[str, Any]:
    """The deterministic figures of ``stats.json`` (JSON-ready).

    Parameters
    ----------
    result : BrokennessResult
    map, reference : OccupancyMap
    rep : Repair, optional
        Computed with :func:`brokenness.report.repair` when not given.

    Returns
    -------
    dict
        :meth:`BrokennessResult.to_dict` without timings, plus ``map``/``reference``
        geometry, per partition ``transform`` (cells, metres, translation norms) and
        ``relative_to_largest`` (the transform ``T_i o T_0^-1`` in the reference frame that
        takes where the largest partition puts a cell to where partition ``i`` puts it),
        ``psi_map`` and ``psi_repaired``.
    """
    if rep is None:
        rep = repair(result, map, reference)
    stats = result.to_dict()
    stats.pop("seconds", None)  # timings belong to info.json (not deterministic)
    parts = []
    t0 = result.partitions[0].transform if result.partitions else None
    for p, d in zip(result.partitions, stats["partitions"], strict=True):
        d = dict(d)
        d.pop("step_seconds", None)
        d["transform"] = _transform_figures(p.transform, reference.resolution)
        if t0 is not None:
            rel = p.transform.compose(t0.inverse())
            d["relative_to_largest"] = _transform_figures(rel, reference.resolution)
        parts.append(d)
    stats["partitions"] = parts
    stats["n_partitions"] = len(parts)
    stats["map"] = _geometry(map)
    stats["reference"] = _geometry(reference)
    stats.update(rep.to_dict())
    return _jsonable(stats)


def _input_record(m: OccupancyMap) -> dict[str, Any]:
    return {"path": m.source, "sha256": file_sha256(m.source) if m.source else None}


def _merge(base: dict[str, Any], extra: Mapping[str, Any]) -> dict[str, Any]:
    out = dict(base)
    for key, value in extra.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), dict):
            out[key] = {**out[key], **value}
        else:
            out[key] = value
    return out


def _member(name: str) -> zipfile.ZipInfo:
    zi = zipfile.ZipInfo(name, date_time=_ZIP_DATE)
    zi.compress_type = zipfile.ZIP_DEFLATED
    zi.external_attr = 0o644 << 16
    return zi


#: Rows of the label image converted and compressed at once (bounds the temporary memory).
_LABEL_ROWS = 256


def _compact(labels: NDArray[np.integer]) -> np.dtype[Any]:
    """int8 when every label fits (fewer than 128 partitions), else int16."""
    if labels.size == 0:
        return np.dtype(np.int8)
    lo, hi = int(labels.min()), int(labels.max())
    return np.dtype(np.int8 if -128 <= lo and hi <= 127 else np.int16)


def _write_zip(
    path: str | os.PathLike[str],
    members: Mapping[str, bytes | None],
    labels: NDArray,
    last: Callable[[], Mapping[str, bytes]] | None = None,
) -> None:
    """Write the result zip atomically, streaming: ``labels.npy`` goes in after
    ``stats.json`` (where ``members`` has ``None``), converted to its compact dtype and
    compressed a strip of rows at a time, never as a whole in memory. ``last``, when given,
    is asked for the final members once the others are written (the overlay, drawn
    meanwhile in another thread)."""
    dtype = _compact(labels)
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        header, {"descr": np.lib.format.dtype_to_descr(dtype), "fortran_order": False,
                 "shape": tuple(labels.shape)}
    )  # fmt: skip
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        with zipfile.ZipFile(fh, "w") as zf:
            for name, data in members.items():
                zi = _member(name)
                if data is not None:
                    zf.writestr(zi, data)
                    continue
                zi.file_size = len(header.getvalue()) + labels.size * dtype.itemsize
                with zf.open(zi, "w") as out:
                    out.write(header.getvalue())
                    for a in range(0, labels.shape[0], _LABEL_ROWS):
                        strip = labels[a : a + _LABEL_ROWS]
                        out.write(np.ascontiguousarray(strip, dtype=dtype).tobytes())
            for name, data in (last() if last is not None else {}).items():
                zf.writestr(_member(name), data)
        fh.flush()
        sync_file(fh)


def _threads_allowed() -> bool:
    """True unless this process runs on one thread (a batch's or a timeline's worker, whose
    processes are the parallelism: :mod:`brokenness._threads`, or a one-core machine):
    OpenCV's thread count says which."""
    import cv2

    return bool(cv2.getNumThreads() > 1)


# -- public API -------------------------------------------------------------------------------
def save_results(
    path: str | os.PathLike[str],
    result: BrokennessResult,
    map: OccupancyMap,
    reference: OccupancyMap,
    *,
    info: Mapping[str, Any] | None = None,
    dpi: int = 150,
    repaired: Repair | None = None,
    overlay: str = "figure",
) -> ResultRecord:
    """Write a self-contained result file (zip) for one evaluated map.

    Parameters
    ----------
    path : path-like
        Destination, conventionally ``*.zip``. Its folder must exist.
    result : BrokennessResult
        The result of :func:`brokenness.compute_brokenness` for ``map`` and ``reference``.
    map, reference : OccupancyMap
        The inputs (their ``source`` paths are recorded with SHA-256 checksums).
    info : mapping, optional
        Extra entries for ``info.json`` (e.g. ``{"labels": {...}, "timings": {...}}``);
        mappings are merged into the default entries of the same name.
    dpi : int
        Resolution of the overlay picture.
    repaired : Repair, optional
        Reuse an already computed :func:`brokenness.report.repair`.
    overlay : {"figure", "fast", "none"}
        The ``overlay.png`` member: the matplotlib figure at ``dpi``
        (:func:`brokenness.report.render_overlay`); the raster picture of
        :mod:`brokenness.report.fast_overlay` (numpy and Pillow, a fraction of the time,
        what a batch writes by default); or no overlay at all.

    Returns
    -------
    ResultRecord
        What was written (as :func:`load_results` would read it back).

    Raises
    ------
    MapError
        If the result does not belong to the map.
    ParameterError
        For an unknown ``overlay``.
    OSError
        If the file cannot be written (nothing is left at ``path`` then).

    Examples
    --------
    >>> save_results("run.zip", result, m, ref, info={"labels": {"system": "gmapping"}})
    ... # doctest: +SKIP
    """
    if overlay not in OVERLAY_KINDS:
        raise ParameterError(f"overlay must be one of {', '.join(OVERLAY_KINDS)}, got {overlay!r}")
    # The picture needs nothing of the rest, and the rest (Psi, the labels' compression) is
    # mostly OpenCV, numpy and zlib, which let another thread run: the picture is drawn in
    # a second thread meanwhile, and goes into the zip last, as it always did.
    second_thread = overlay != "none" and _threads_allowed()
    with ThreadPoolExecutor(max_workers=1) if second_thread else nullcontext() as pool:
        if pool is not None:
            drawn = pool.submit(_overlay_png, overlay, result, map, reference, dpi)
            picture: Callable[[], bytes | None] = drawn.result
        else:
            picture = partial(_overlay_png, overlay, result, map, reference, dpi)
        return _save(path, result, map, reference, info, repaired, overlay, picture)


def _save(
    path: str | os.PathLike[str],
    result: BrokennessResult,
    map: OccupancyMap,
    reference: OccupancyMap,
    info: Mapping[str, Any] | None,
    repaired: Repair | None,
    overlay: str,
    picture: Callable[[], bytes | None],
) -> ResultRecord:
    """:func:`save_results` once the overlay is on its way (``picture`` gives its PNG)."""
    rep = repaired if repaired is not None else repair(result, map, reference)
    stats = build_stats(result, map, reference, rep)
    base: dict[str, Any] = {
        "format": FORMAT_NAME,
        "format_version": FORMAT_VERSION,
        "package": "brokenness",
        "version": __version__,
        "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "method": result.method,
        "parameters": dict(result.parameters),
        "inputs": {"map": _input_record(map), "reference": _input_record(reference)},
        "timings": {
            "compute_seconds": result.seconds,
            "step_seconds": list(result.step_seconds),
        },
        "labels": {},
        "overlay": overlay,
    }
    info_dict = _jsonable(_merge(base, info or {}))
    labels = np.asarray(result.labels)
    members: dict[str, bytes | None] = {
        "info.json": _dumps(info_dict),
        "stats.json": _dumps(stats),
        "labels.npy": None,  # streamed from ``labels``
    }
    png: bytes | None = None

    def last() -> dict[str, bytes]:
        nonlocal png
        png = picture()
        return {} if png is None else {"overlay.png": png}

    _write_zip(path, members, labels, last)
    return ResultRecord(
        info_dict, stats, labels.astype(np.int16, copy=False), png or b"", Path(path)
    )


def _overlay_png(
    kind: str,
    result: BrokennessResult,
    map: OccupancyMap,
    reference: OccupancyMap,
    dpi: int,
) -> bytes | None:
    if kind == "none":
        return None
    if kind == "fast":
        from .fast_overlay import fast_overlay_png

        return fast_overlay_png(result, map, reference)
    from .overlay import render_overlay  # matplotlib: loaded only for the figure

    png = io.BytesIO()
    render_overlay(result, map, reference, png, dpi=dpi)
    return png.getvalue()


#: Largest ``info.json`` / ``stats.json`` accepted in a result file (declared size), bytes.
MAX_JSON_MEMBER_BYTES: int = 16 << 20
#: Largest ``overlay.png`` accepted in a result file (declared size), bytes.
MAX_OVERLAY_MEMBER_BYTES: int = 64 << 20


def _reject_constant(value: str) -> Any:
    raise ValueError(f"non-finite number {value}")


def _finite_float(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(f"non-finite number {text}")
    return value


def parse_json(data: bytes | str) -> Any:
    """Strict JSON: ``NaN``, ``Infinity`` and overflowing numbers (``1e400``) are refused.

    Raises
    ------
    ValueError
        For invalid JSON (:class:`json.JSONDecodeError`), non-finite numbers, text that is
        not UTF-8, or nesting too deep.
    """
    try:
        return json.loads(data, parse_constant=_reject_constant, parse_float=_finite_float)
    except RecursionError:
        raise ValueError("JSON nested too deeply") from None


def _member_limits() -> dict[str, int]:
    return {
        "info.json": MAX_JSON_MEMBER_BYTES,
        "stats.json": MAX_JSON_MEMBER_BYTES,
        "labels.npy": 2 * max_cells() + (1 << 16),  # int16 labels and the .npy header
        "overlay.png": MAX_OVERLAY_MEMBER_BYTES,
    }


def _read_member(zf: zipfile.ZipFile, name: str, limit: int, p: Path) -> bytes:
    """A member's bytes, refused from its declared size before anything is inflated.

    ``zipfile`` never inflates more than a member's declared ``file_size`` (and checks its
    CRC), so the bound on the declared size bounds the memory.
    """
    member = zf.getinfo(name)
    if member.file_size > limit:
        raise ResultFileError(
            f"{p}: {name} declares {member.file_size} bytes uncompressed, more than the "
            f"limit of {limit} bytes"
        )
    return zf.read(member)


def _degree_ok(value: Any) -> bool:
    return value is None or (isinstance(value, int) and not isinstance(value, bool) and value >= 0)


# -- the fields of a result file, checked once where it is read --------------------------------
@dataclass(frozen=True)
class _Kind:
    """What a field of ``info.json`` or ``stats.json`` may hold (``null`` always may be).

    ``fields`` are an object's known fields (others are free: callers add their own),
    ``required`` those of them that must be there and not ``null``, and ``each`` what every
    item of a list (or every value of an object) must be.
    """

    what: str
    test: Callable[[Any], bool]
    fields: Mapping[str, _Kind] | None = None
    required: tuple[str, ...] = ()
    each: _Kind | None = None


class _FieldError(Exception):
    """A field of a result file is not what the format says (``name``: where it is)."""

    def __init__(self, name: str, problem: str) -> None:
        super().__init__(f"{name} {problem}")


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _object(
    fields: Mapping[str, _Kind] | None = None,
    required: tuple[str, ...] = (),
    each: _Kind | None = None,
) -> _Kind:
    return _Kind("an object", lambda v: isinstance(v, dict), fields, required, each)


def _list(each: _Kind) -> _Kind:
    return _Kind("a list", lambda v: isinstance(v, list), each=each)


_TEXT = _Kind("text", lambda v: isinstance(v, str))
_NUMBER = _Kind("a number", _is_number)
_SHARE = _Kind("a share in [0, 1]", lambda v: _is_number(v) and 0 <= v <= 1)
_COUNT = _Kind(
    "a whole number >= 0", lambda v: isinstance(v, int) and not isinstance(v, bool) and v >= 0
)
_FLAG = _Kind("true or false", lambda v: isinstance(v, bool))
_PAIR = _Kind(
    "a pair of numbers", lambda v: isinstance(v, list) and len(v) == 2 and all(map(_is_number, v))
)
_LABEL = _Kind("text, a number or null", lambda v: v is None or isinstance(v, str | int | float))
_TRANSFORM = _object(
    {
        "rotation_deg": _NUMBER,
        "translation_cells": _PAIR,
        "scale": _NUMBER,
        "world": _object({"rotation_deg": _NUMBER, "translation_m": _PAIR}),
        "translation_norm_cells": _NUMBER,
        "translation_norm_m": _NUMBER,
    }
)
_PARTITION = _object(
    {
        "index": _COUNT,
        "cells": _COUNT,
        "fraction": _SHARE,
        "transform": _TRANSFORM,
        "relative_to_largest": _TRANSFORM,
        "confidence": _NUMBER,
        "rotation_offset_deg": _NUMBER,
        "displacement_cells": _NUMBER,
        "displacement_m": _NUMBER,
        "contradiction": _NUMBER,
        "contradiction_bound": _NUMBER,
        "acceptance": _NUMBER,
    },
    required=("index", "cells", "fraction"),
)
_GEOMETRY = _object(
    {
        "rows": _COUNT,
        "cols": _COUNT,
        "resolution": _NUMBER,
        "origin": _list(_NUMBER),
        "occupied_cells": _COUNT,
    }
)
#: The fields of ``info.json`` this package defines (and reads back).
_INFO = _object(
    {
        "format_version": _COUNT,
        "package": _TEXT,
        "version": _TEXT,
        "created": _TEXT,
        "method": _TEXT,
        "parameters": _object(),
        "inputs": _object(),
        "timings": _object(
            {
                "compute_seconds": _NUMBER,
                "load_seconds": _NUMBER,
                "total_seconds": _NUMBER,
                "step_seconds": _list(_NUMBER),
            }
        ),
        "labels": _object(each=_LABEL),
        "overlay": _TEXT,
        "timeline": _object(),
    }
)
#: The fields of ``stats.json`` (:func:`build_stats`).
_STATS = _object(
    {
        "measured": _FLAG,
        "reason": _TEXT,
        "contradiction": _NUMBER,
        "contradiction_bound": _NUMBER,
        "occupied_cells": _COUNT,
        "unassigned_cells": _COUNT,
        "unassigned_fraction": _SHARE,
        "largest_fraction": _SHARE,
        "n_partitions": _COUNT,
        "partitions": _list(_PARTITION),
        "method": _TEXT,
        "parameters": _object(),
        "map": _GEOMETRY,
        "reference": _GEOMETRY,
        "psi_map": _NUMBER,
        "psi_repaired": _NUMBER,
    }
)


def _json_kind(value: Any) -> str:
    """How ``value`` shows in a message: its JSON type, and a short text of a scalar."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, dict | list):
        return "an object" if isinstance(value, dict) else "a list"
    kind = "text" if isinstance(value, str) else "a number"
    return f"{kind} {reprlib.repr(value)}"


def _validate(value: Any, kind: _Kind, name: str) -> None:
    """Raise :class:`_FieldError` unless ``value`` (not ``null``) is of ``kind``, and so are
    its known fields and items."""
    if not kind.test(value):
        raise _FieldError(name, f"must be {kind.what}, got {_json_kind(value)}")
    for key in kind.required:
        if value.get(key) is None:
            raise _FieldError(_at(name, key), "is missing")
    for key, sub in (kind.fields or {}).items():
        if value.get(key) is not None:
            _validate(value[key], sub, _at(name, key))
    if kind.each is not None:
        items = value.items() if isinstance(value, dict) else enumerate(value)
        for index, item in items:
            _validate(item, kind.each, _at(name, index))


def _at(name: str, key: str | int) -> str:
    """Where a field or item is: ``partitions[0].transform``."""
    if isinstance(key, int):
        return f"{name}[{key}]"
    return f"{name}.{key}" if name else key


def _check_fields(p: Path, info: dict[str, Any], stats: dict[str, Any]) -> None:
    """Every field this package reads from a result file, of the type the format says, and
    the degree consistent with the partitions: one check, where the file is read, so that
    no reader meets a field of another type (a :class:`ResultFileError` naming the field)."""
    for member, doc, kind in (("info.json", info, _INFO), ("stats.json", stats, _STATS)):
        try:
            _validate(doc, kind, "")
        except _FieldError as exc:
            raise ResultFileError(f"{p}: {member}: {exc}") from None
    measured, degree = stats.get("measured", True), stats["degree"]
    parts = len(stats.get("partitions") or [])
    shown = "null" if degree is None else reprlib.repr(degree)
    if measured is True and degree != parts - 1:
        raise ResultFileError(
            f"{p}: stats.json: a measured degree must be the partitions less one, got degree "
            f"{shown} with {parts} partition{'' if parts == 1 else 's'}"
        )
    if measured is not True and degree is not None:
        raise ResultFileError(
            f"{p}: stats.json: degree {shown} but measured is {_json_kind(measured)}"
        )


def load_results(path: str | os.PathLike[str]) -> ResultRecord:
    """Read a result file written by :func:`save_results`.

    Every member's declared uncompressed size is checked before it is read (a zip bomb is
    refused, not inflated); JSON with ``NaN`` or ``Infinity`` is refused; every failure of the
    zip, zlib, JSON and numpy readers becomes a one-line :class:`ResultFileError`. Every field
    of ``info.json`` and ``stats.json`` that this package reads is checked here, once, to be
    of the type the format says (``parameters`` an object, a partition's ``fraction`` a share
    in [0, 1], ``timings`` an object of numbers...; fields a caller added are free), and a
    measured degree to be the partitions less one: the readers (``compare``, ``report``,
    a resumed batch or timeline) never meet a field of another type.

    Parameters
    ----------
    path : path-like

    Returns
    -------
    ResultRecord

    Raises
    ------
    ResultFileError
        If the file is missing, not a regular file, too large, not a zip, damaged, not a
        brokenness result file, or has a field of the wrong type (the message names it).
    """
    from ..io._files import check_regular, open_nonblocking
    from ..io.arrays import check_npy_header

    p = Path(path)
    try:
        st = check_regular(p, "result file")
    except BrokennessError as exc:
        text = str(exc)
        if "no such file" in text:
            text = f"{p}: no such result file"
        raise ResultFileError(text) from None
    if st.st_size > max_file_bytes():
        raise ResultFileError(
            f"{p}: {st.st_size} bytes, more than the limit of {max_file_bytes()} bytes"
        )
    limits = _member_limits()
    try:
        with os.fdopen(open_nonblocking(p), "rb") as fh, zipfile.ZipFile(fh) as zf:
            names = set(zf.namelist())
            missing = [m for m in _REQUIRED if m not in names]
            if missing:
                raise ResultFileError(f"{p}: not a brokenness result file (no {missing[0]})")
            raw = {m: _read_member(zf, m, limits[m], p) for m in _MEMBERS if m in names}
        info = parse_json(raw["info.json"])
        stats = parse_json(raw["stats.json"])
        check_npy_header(raw["labels.npy"], f"{p}: labels.npy")
        labels = np.load(io.BytesIO(raw["labels.npy"]), allow_pickle=False)
        overlay = raw.get("overlay.png", b"")
    except ResultFileError:
        raise
    except BrokennessError as exc:  # the labels' header
        raise ResultFileError(f"{p}: damaged result file ({exc})") from None
    except (zipfile.BadZipFile, zipfile.LargeZipFile, EOFError) as exc:
        raise ResultFileError(f"{p}: not a valid zip file ({_one_line(exc)})") from None
    except MemoryError:
        raise ResultFileError(f"{p}: damaged result file (too large to read)") from None
    except Exception as exc:  # zlib.error, bad JSON / npy inside, unsupported zip features
        reason = _one_line(exc) or type(exc).__name__
        raise ResultFileError(f"{p}: damaged result file ({reason})") from None
    if not isinstance(info, dict) or info.get("format") != FORMAT_NAME:
        raise ResultFileError(f"{p}: not a brokenness result file")
    if not isinstance(stats, dict) or "degree" not in stats:
        raise ResultFileError(f"{p}: stats.json has no degree")
    if not _degree_ok(stats["degree"]):
        raise ResultFileError(
            f"{p}: stats.json has an invalid degree {str(stats['degree'])[:40]!r}"
        )
    _check_fields(p, info, stats)
    if not isinstance(labels, np.ndarray) or labels.ndim != 2:
        raise ResultFileError(f"{p}: labels.npy is not a 2D array")
    if labels.dtype.kind not in "iu":
        raise ResultFileError(f"{p}: labels.npy is not an integer array ({labels.dtype})")
    if labels.size and not (-2 <= labels.min() and labels.max() <= np.iinfo(np.int16).max):
        raise ResultFileError(f"{p}: labels.npy has labels outside [-2, 32767]")
    return ResultRecord(info, stats, labels.astype(np.int16, copy=False), overlay, p)


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split())
