"""Fuzzing the readers: whatever the bytes, only the package's typed errors escape.

Hypothesis feeds the map loaders (PGM, PNG, .npy, map YAML), the manifest reader and the
result reader with random bytes and with valid files mutated byte by byte (the more
productive half: it gets past the magic numbers into the headers and payloads). Each reader
either succeeds or raises a :class:`brokenness.BrokennessError`; anything else (IndexError,
zlib.error, OverflowError, struct.error...) is a bug. Bounded: the whole file runs in a
few seconds.
"""

from __future__ import annotations

import io
import tempfile
import warnings
import zipfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from PIL import Image

import brokenness
import brokenness.report
from brokenness.batch import read_manifest
from brokenness.io.pnm import encode_pgm
from brokenness.report import load_results

SETTINGS = settings(
    max_examples=60,
    deadline=None,
    derandomize=True,  # the same inputs on every run: deterministic CI
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)


def _grid() -> np.ndarray:
    img = np.full((12, 16), 254, np.uint8)
    img[2, 2:14] = img[9, 2:14] = 0
    img[4:7, 6:9] = 205
    return img


def _png() -> bytes:
    buf = io.BytesIO()
    Image.fromarray(_grid()).save(buf, format="PNG")
    return buf.getvalue()


def _npy() -> bytes:
    buf = io.BytesIO()
    np.save(buf, (_grid() == 0).astype(np.int8))
    return buf.getvalue()


YAML = b"image: m.pgm\nresolution: 0.05\norigin: [-1.0, -2.0, 0.0]\nnegate: 0\n"
YAML += b"occupied_thresh: 0.65\nfree_thresh: 0.196\nmode: trinary\n"
SEEDS = {
    ".pgm": encode_pgm(_grid()),
    ".png": _png(),
    ".npy": _npy(),
    ".yaml": YAML,
}


@st.composite
def mutated(draw: st.DrawFn, seed: bytes) -> bytes:
    """``seed`` with a few bytes replaced, inserted or cut, or truncated, or random bytes."""
    kind = draw(st.sampled_from(["flip", "flip", "cut", "insert", "random"]))
    data = bytearray(seed)
    if kind == "random":
        return draw(st.binary(max_size=200))
    if kind == "cut":
        return bytes(data[: draw(st.integers(0, len(data)))])
    for _ in range(draw(st.integers(1, 6))):
        at = draw(st.integers(0, len(data) - 1))
        if kind == "insert":
            data[at:at] = draw(st.binary(min_size=1, max_size=8))
        else:
            data[at] = draw(st.integers(0, 255))
    return bytes(data)


def _only_typed_errors(call, *args):  # type: ignore[no-untyped-def]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # MapWarning, Pillow's warnings: not errors
        try:
            call(*args)
        except brokenness.BrokennessError as exc:
            assert "\n" not in str(exc)


@pytest.mark.parametrize("suffix", sorted(SEEDS))
def test_map_loaders(suffix: str) -> None:
    @SETTINGS
    @given(data=mutated(SEEDS[suffix]))
    def check(data: bytes) -> None:
        with tempfile.TemporaryDirectory() as tmp:
            folder = Path(tmp)
            (folder / f"m{suffix}").write_bytes(data)
            if suffix == ".yaml":  # the image the YAML names
                (folder / "m.pgm").write_bytes(SEEDS[".pgm"])
            _only_typed_errors(brokenness.load_map, folder / f"m{suffix}")

    check()


MANIFEST_CSV = (
    b"map,reference,system,noise,seed\na.yaml,r.yaml,gmapping,0.1,1\nb.pgm,r.yaml,x,0,2\n"
)
MANIFEST_YAML = (
    b"defaults: {reference: r.yaml, dataset: office}\noptions: {threshold: 2}\n"
    b"pairs:\n  - {map: a.pgm, system: gmapping, noise: 0.1, seed: 1}\n  - {map: b.pgm}\n"
)


@pytest.mark.parametrize(("suffix", "seed"), [(".csv", MANIFEST_CSV), (".yaml", MANIFEST_YAML)])
def test_manifest_reader(suffix: str, seed: bytes) -> None:
    @SETTINGS
    @given(data=mutated(seed))
    def check(data: bytes) -> None:
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / f"runs{suffix}"
            path.write_bytes(data)
            _only_typed_errors(read_manifest, path)

    check()


@pytest.fixture(scope="module")
def result_bytes(tmp_path_factory: pytest.TempPathFactory) -> bytes:
    folder = tmp_path_factory.mktemp("fuzz")
    states = np.zeros((40, 40), np.int8)
    states[5, 5:35] = states[5:35, 5] = states[34, 5:35] = states[5:35, 34] = 1
    m = brokenness.OccupancyMap(states, 0.05, (0.0, 0.0, 0.0))
    result = brokenness.compute_brokenness(m, m)
    brokenness.report.save_results(folder / "r.zip", result, m, m, dpi=20)
    return (folder / "r.zip").read_bytes()


def _stored(data: bytes) -> bytes:
    """The same zip with every member stored (uncompressed): mutations reach the JSON."""
    out = io.BytesIO()
    with zipfile.ZipFile(io.BytesIO(data)) as zin, zipfile.ZipFile(out, "w") as zout:
        for info in zin.infolist():
            zout.writestr(info.filename, zin.read(info), compress_type=zipfile.ZIP_STORED)
    return out.getvalue()


@pytest.mark.parametrize("stored", [False, True])
def test_result_reader(result_bytes: bytes, stored: bool) -> None:
    seed = _stored(result_bytes) if stored else result_bytes

    @SETTINGS
    @given(data=mutated(seed))
    def check(data: bytes) -> None:
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "r.zip"
            path.write_bytes(data)
            _only_typed_errors(load_results, path)
            _only_typed_errors(brokenness.report.collect_results, [path])

    check()
