"""Batch manifests: the list of map/reference pairs to evaluate, with labels.

A manifest is a CSV or YAML file. Every pair has a ``map`` and a ``reference`` path
(relative paths are relative to the manifest's folder) and optional labels such as
``system``, ``dataset``, ``noise``, ``seed``: free-form columns that the summary tables and
``brokenness compare`` group by. Two label columns also set options of
:func:`brokenness.compute_brokenness` for their pair: ``method`` and ``seed``.

CSV::

    map,reference,system,noise,seed
    runs/gmapping_0.1_1.pgm,ref/office.yaml,gmapping,0.1,1

YAML (a list of pairs, or a mapping with ``pairs``, optional ``defaults`` applied to every
pair, optional ``options`` passed to :func:`brokenness.compute_brokenness` and optional
``overlays``, the overlay picture of every result zip: ``fast``, the default, ``figure``
or ``none``, as ``brokenness batch --overlays``, which wins)::

    defaults: {reference: ref/office.yaml, dataset: office}
    options: {threshold: 2}
    overlays: fast
    pairs:
      - {map: runs/gmapping_0.1_1.pgm, system: gmapping, noise: 0.1, seed: 1}

A YAML manifest is read by the package's one strict YAML reader
(:func:`brokenness.io._yaml.parse_yaml`): duplicate keys and aliases (``*name``) are refused
(``defaults`` does what anchors would). Messages echo values shortened
(:func:`brokenness.io._files.shown`), so a hostile manifest cannot make them long.
"""

from __future__ import annotations

import csv
import hashlib
import json
import os
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import BrokennessError
from ..io._files import REASON_CHARS, one_line, path_text, read_file_bytes, shown
from ..limits import MAX_MANIFEST_BYTES

__all__ = [
    "COMPUTE_LABELS",
    "OVERLAY_KINDS",
    "Manifest",
    "ManifestError",
    "Pair",
    "pairs_of",
    "read_manifest",
]

#: Label columns that are also passed to :func:`brokenness.compute_brokenness`.
COMPUTE_LABELS: tuple[str, ...] = ("method", "seed")
#: The overlay pictures a batch can put in its result zips (``overlays``), as
#: :data:`brokenness.report.results.OVERLAY_KINDS` (named here so that reading a manifest,
#: and checking a batch's options, never loads the pipeline).
OVERLAY_KINDS: tuple[str, ...] = ("figure", "fast", "none")
_PATH_COLUMNS = ("map", "reference")


class ManifestError(BrokennessError, ValueError):
    """A manifest cannot be read: missing, wrong format, missing columns, bad rows."""


@dataclass(frozen=True)
class Pair:
    """One map/reference pair of a manifest.

    Attributes
    ----------
    map, reference : Path
        Absolute paths (resolved against the manifest's folder).
    map_text, reference_text : str
        The paths as written in the manifest (they make the stable :attr:`id`).
    labels : dict of str to str
        Every other column, in manifest order (empty values dropped).
    row : int
        1-based position of the pair in the manifest (for messages).
    """

    map: Path
    reference: Path
    map_text: str
    reference_text: str
    labels: dict[str, str] = field(default_factory=dict, hash=False)
    row: int = 0

    @property
    def id(self) -> str:
        """Stable 12-hex-digit identifier from the paths as written and the labels."""
        key = json.dumps(
            {"map": self.map_text, "reference": self.reference_text, "labels": self.labels},
            sort_keys=True,
        )
        return hashlib.sha256(key.encode()).hexdigest()[:12]

    @property
    def stem(self) -> str:
        """File name stem of this pair's outputs: readable map name plus :attr:`id`."""
        name = re.sub(r"[^A-Za-z0-9._-]+", "_", Path(self.map_text).stem).strip("._")[:40]
        return f"{name or 'map'}-{self.id}"

    @property
    def result_name(self) -> str:
        """File name of this pair's result zip."""
        return f"{self.stem}.zip"

    def compute_options(self) -> dict[str, Any]:
        """Options of :func:`brokenness.compute_brokenness` set by this pair's labels.

        Raises
        ------
        ManifestError
            If ``seed`` is not an integer.
        """
        out: dict[str, Any] = {}
        if "method" in self.labels:
            out["method"] = self.labels["method"]
        if "seed" in self.labels:
            try:
                out["seed"] = int(self.labels["seed"])
            except ValueError:
                raise ManifestError(
                    f"row {self.row}: seed must be an integer, got {shown(self.labels['seed'])}"
                ) from None
        return out


@dataclass(frozen=True)
class Manifest:
    """The pairs of a manifest and the options shared by all of them.

    Attributes
    ----------
    pairs : tuple of Pair
    options : dict
        Keyword options for :func:`brokenness.compute_brokenness` (YAML ``options``).
    path : Path or None
        The manifest file.
    overlays : str or None
        The overlay picture of the result zips (YAML ``overlays``: ``"fast"``,
        ``"figure"`` or ``"none"``); ``None`` when the manifest does not say.
    """

    pairs: tuple[Pair, ...]
    options: dict[str, Any] = field(default_factory=dict, hash=False)
    path: Path | None = None
    overlays: str | None = None

    @property
    def label_names(self) -> list[str]:
        """Every label name used by some pair, in first-seen order."""
        names: dict[str, None] = {}
        for p in self.pairs:
            names.update(dict.fromkeys(p.labels))
        return list(names)


def _text(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value).strip()


def _absolute(path: Path) -> Path:
    """``path.resolve()``, or the absolute path when resolving fails (a symbolic link loop is
    reported by the map reader, precisely, when the pair is evaluated)."""
    try:
        return path.resolve()
    except (OSError, RuntimeError, ValueError):
        return Path(os.path.abspath(path))


def _make_pair(entry: Mapping[str, Any], row: int, base: Path, where: str) -> Pair:
    values = {str(k).strip(): _text(v) for k, v in entry.items() if k is not None}
    for col in _PATH_COLUMNS:
        if not values.get(col):
            raise ManifestError(f"{where} row {row}: no {col!r} path")
    labels = {k: v for k, v in values.items() if k not in _PATH_COLUMNS and v != ""}
    for k in labels:
        if not k:
            raise ManifestError(f"{where} row {row}: a column has no name")
    paths = [Path(os.path.expanduser(values[c])) for c in _PATH_COLUMNS]
    resolved = [p if p.is_absolute() else (base / p) for p in paths]
    return Pair(
        map=_absolute(resolved[0]),
        reference=_absolute(resolved[1]),
        map_text=values["map"],
        reference_text=values["reference"],
        labels=labels,
        row=row,
    )


def _read_text(path: Path) -> str:
    """The manifest's text: a regular file of at most MAX_MANIFEST_BYTES, UTF-8."""
    try:
        data = read_file_bytes(path, MAX_MANIFEST_BYTES, "manifest")
    except BrokennessError as exc:
        raise ManifestError(str(exc)) from None
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise ManifestError(f"{path_text(path)}: not a text file (not UTF-8)") from None


def _read_csv(path: Path) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    try:
        return _parse_csv(path, _read_text(path))
    except csv.Error as exc:  # NUL bytes, a field over csv.field_size_limit()...
        reason = one_line(exc, REASON_CHARS)
        raise ManifestError(f"{path_text(path)}: invalid CSV ({reason})") from None


def _parse_csv(path: Path, text: str) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    numbered = [
        (n, ln)
        for n, ln in enumerate(text.splitlines(), start=1)
        if ln.strip() and not ln.lstrip().startswith("#")
    ]
    name = path_text(path)
    if not numbered:
        raise ManifestError(f"{name}: empty manifest")
    reader = csv.DictReader([ln for _n, ln in numbered])
    header = [h.strip() for h in (reader.fieldnames or [])]
    missing = [c for c in _PATH_COLUMNS if c not in header]
    if missing:
        raise ManifestError(
            f"{name}: the header must name the columns 'map' and 'reference' "
            f"(missing {', '.join(repr(m) for m in missing)}; header is {shown(header)})"
        )
    if len(set(header)) != len(header):
        raise ManifestError(f"{name}: duplicate column names in the header")
    rows = []
    for i, raw in enumerate(reader, start=1):
        line = numbered[reader.line_num - 1][0]  # the file's line (comments, blanks skipped)
        if None in raw:
            raise ManifestError(f"{name} row {i} (line {line}): more values than columns")
        if any(v is None for v in raw.values()):  # DictReader fills missing fields with None
            given = sum(v is not None for v in raw.values())
            raise ManifestError(
                f"{name} row {i} (line {line}): fewer values than columns ({given} of "
                f"{len(header)}; leave a value empty with a comma)"
            )
        rows.append({k.strip(): v for k, v in raw.items()})
    return rows, {}


def _read_yaml(path: Path) -> tuple[list[dict[str, Any]], dict[str, Any], str | None]:
    from ..io._yaml import parse_yaml

    name = path_text(path)
    try:
        doc = parse_yaml(_read_text(path), name)
    except ManifestError:
        raise
    except BrokennessError as exc:  # duplicate keys, bad tagged values, nesting too deep...
        raise ManifestError(f"{exc}".replace("invalid YAML", "not valid YAML", 1)) from None
    options: dict[str, Any] = {}
    defaults: dict[str, Any] = {}
    overlays: str | None = None
    if isinstance(doc, Mapping):
        unknown = set(doc) - {"pairs", "defaults", "options", "overlays"}
        if unknown:
            raise ManifestError(
                f"{name}: unknown top-level key(s) {shown(sorted(map(str, unknown)))}; "
                "expected pairs, defaults, options, overlays"
            )
        if doc.get("overlays") is not None:
            overlays = _overlays(doc["overlays"], path)
        entries = doc.get("pairs")
        defaults = doc.get("defaults") or {}
        options = doc.get("options") or {}
        if not isinstance(defaults, Mapping) or not isinstance(options, Mapping):
            raise ManifestError(f"{name}: 'defaults' and 'options' must be mappings")
    else:
        entries = doc
    if not isinstance(entries, list):
        raise ManifestError(f"{name}: expected a list of pairs (each with map and reference)")
    rows = []
    for i, entry in enumerate(entries, start=1):
        if not isinstance(entry, Mapping):
            raise ManifestError(f"{name} row {i}: a pair must be a mapping, got {shown(entry)}")
        rows.append({**defaults, **entry})
    return rows, dict(options), overlays


def _overlays(value: Any, path: Path) -> str:
    if not isinstance(value, str) or value not in OVERLAY_KINDS:
        raise ManifestError(
            f"{path_text(path)}: overlays must be one of {', '.join(OVERLAY_KINDS)}, "
            f"got {shown(value)}"
        )
    return value


def read_manifest(path: str | os.PathLike[str]) -> Manifest:
    """Read a CSV (``.csv``/``.tsv``) or YAML (``.yaml``/``.yml``) manifest.

    Parameters
    ----------
    path : path-like

    Returns
    -------
    Manifest

    Raises
    ------
    ManifestError
        If the file is missing, not a regular file, larger than
        :data:`~brokenness.limits.MAX_MANIFEST_BYTES`, of an unknown kind, invalid CSV or
        YAML (duplicate keys, aliases, bad tagged values), has no ``map``/``reference`` columns,
        has a row without them, no pairs, or the same pair twice.

    Examples
    --------
    >>> m = read_manifest("runs.csv")  # doctest: +SKIP
    >>> [p.labels["system"] for p in m.pairs]  # doctest: +SKIP
    """
    p = Path(path)
    name = path_text(p)
    if not os.path.lexists(p):
        raise ManifestError(f"{name}: no such manifest file")
    suffix = p.suffix.lower()
    overlays = None
    if suffix == ".csv":
        rows, options = _read_csv(p)
    elif suffix in (".yaml", ".yml"):
        rows, options, overlays = _read_yaml(p)
    else:
        raise ManifestError(f"{name}: a manifest must be .csv, .yaml or .yml")
    base = _absolute(p).parent
    pairs = tuple(_make_pair(r, i, base, name) for i, r in enumerate(rows, start=1))
    if not pairs:
        raise ManifestError(f"{name}: the manifest lists no pairs")
    seen: dict[str, int] = {}
    for pair in pairs:
        pair.compute_options()  # validate seeds early
        if pair.id in seen:
            raise ManifestError(
                f"{name}: rows {seen[pair.id]} and {pair.row} are the same pair "
                "(same paths and labels)"
            )
        seen[pair.id] = pair.row
    return Manifest(pairs, options, p, overlays)


def pairs_of(manifest: Manifest | str | os.PathLike[str] | Sequence[Pair]) -> Manifest:
    """A :class:`Manifest` from a manifest, a path or a sequence of pairs."""
    if isinstance(manifest, Manifest):
        return manifest
    if isinstance(manifest, (str, os.PathLike)):
        return read_manifest(manifest)
    return Manifest(tuple(manifest))
