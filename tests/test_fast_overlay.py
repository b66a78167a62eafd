"""The fast raster overlay of a batch, the batch's --overlays, and one thread per worker."""

from __future__ import annotations

import io
import os
import subprocess
import sys
import zipfile

import numpy as np
import pytest
import yaml
from PIL import Image

import brokenness
import brokenness.cli.main as cli_main
from brokenness import OccupancyMap, RigidTransform
from brokenness.batch import ManifestError, read_manifest, run_batch
from brokenness.errors import ParameterError
from brokenness.measure.result import UNASSIGNED, BrokennessResult, Partition
from brokenness.report import load_results, save_results
from brokenness.report.fast_overlay import fast_overlay_png
from brokenness.report.raster import N_COLOURS, partition_style

# cells of each partition (row, col) in a 60 x 60 map, all unknown but these cells
CELLS = {
    0: [(10, 12), (10, 13), (11, 12), (30, 20)],
    1: [(20, 40), (40, 41)],
    2: [(45, 15), (46, 30), (47, 45)],
}
UNASSIGNED_CELL = (25, 30)
REFERENCE_CELL = (35, 35)  # a reference wall no map cell covers


def _case(cells=CELLS, unassigned=(UNASSIGNED_CELL,)):
    states = np.full((60, 60), -1, np.int8)
    labels = np.full((60, 60), -1, np.int16)
    for index, rc in cells.items():
        for r, c in rc:
            states[r, c] = 1
            labels[r, c] = index
    for r, c in unassigned:
        states[r, c] = 1
        labels[r, c] = UNASSIGNED
    ref_states = states.copy()
    ref_states[REFERENCE_CELL] = 1
    total = int((states == 1).sum())
    parts = tuple(
        Partition(i, len(rc), len(rc) / total, RigidTransform.identity(), 0.9, 0.0, 0.0, None, 0.0)
        for i, rc in cells.items()
    )
    result = BrokennessResult(
        len(parts) - 1, parts, labels, total, len(unassigned), "ifmi", {}, 0.0
    )
    return OccupancyMap(states), OccupancyMap(ref_states), result


def _rgb(png: bytes) -> np.ndarray:
    with Image.open(io.BytesIO(png)) as im:
        return np.asarray(im.convert("RGB")).astype(int)


def _cells_of(rgb: np.ndarray, colour, origin, scale) -> set[tuple[int, int]]:
    """Map-part cells (row, col) whose pixels have ``colour``."""
    ys, xs = np.nonzero(np.all(rgb == colour, axis=2))
    oy, ox = origin
    return {((y - oy) // scale, (x - ox) // scale) for y, x in zip(ys, xs, strict=True)}


def test_each_partition_colour_is_where_its_cells_land():
    m, ref, result = _case()
    rgb = _rgb(fast_overlay_png(result, m, ref))
    # the map part is unknown grey but for the cells: its box locates it in the picture
    unknown = np.all(rgb == 232, axis=2)
    ys, xs = np.nonzero(unknown)
    origin = (0, 0)
    part = rgb[ys.min() : ys.max() + 1, xs.min() : xs.max() + 1]  # the map part alone
    # a small map is enlarged by an integer factor: partition 1's two lone cells tell it
    colour1 = np.round(np.asarray(partition_style(1)[0]) * 255).astype(int)
    scale = int(round(np.sqrt(np.all(part == colour1, axis=2).sum() / len(CELLS[1]))))
    assert scale >= 3  # cells of 3 pixels or more: walls are not widened
    found = {}
    for index in CELLS:
        colour = np.round(np.asarray(partition_style(index)[0]) * 255).astype(int)
        found[index] = _cells_of(part, colour, origin, scale)
    found["unassigned"] = _cells_of(part, (0, 0, 0), origin, scale)
    found["reference"] = _cells_of(part, (158, 158, 158), origin, scale)
    expected = {**CELLS, "unassigned": [UNASSIGNED_CELL], "reference": [REFERENCE_CELL]}
    # one offset (the explored box's corner) takes every expected cell to the found one
    all_found = set().union(*found.values())
    all_expected = {rc for v in expected.values() for rc in v}
    assert len(all_found) == len(all_expected)
    dy = min(r for r, _ in all_expected) - min(r for r, _ in all_found)
    dx = min(c for _, c in all_expected) - min(c for _, c in all_found)
    for key, rc in expected.items():
        assert found[key] == {(r - dy, c - dx) for r, c in rc}, key
    # the black of the text legend is below the map part, not in it
    legend = rgb[ys.max() + 1 :]
    assert np.any(np.all(legend == 0, axis=2))


def test_partitions_beyond_the_palette_are_striped():
    cells = {
        i: [(5 + 3 * (i // 6), 5 + 8 * (i % 6)), (6 + 3 * (i // 6), 5 + 8 * (i % 6))]
        for i in range(N_COLOURS + 2)
    }
    m, ref, result = _case(cells, ())
    rgb = _rgb(fast_overlay_png(result, m, ref))
    striped = N_COLOURS  # the first partition to reuse a colour
    plain, stripes = partition_style(striped)
    assert stripes == 1
    colour = np.round(np.asarray(plain) * 255).astype(int)
    dark = np.round(np.asarray(plain) * 0.35 * 255).astype(int)
    assert np.any(np.all(np.abs(rgb - dark) <= 1, axis=2))  # its dark stripes are drawn
    assert np.any(np.all(rgb == colour, axis=2))


def test_a_huge_map_gives_a_bounded_picture():
    states = np.full((6000, 5000), -1, np.int8)
    states[100:5900, 100:4900] = 0
    states[3000, 100:4900] = 1  # one wall, a cell thin
    m = OccupancyMap(states)
    result = brokenness.compute_brokenness(m, m)
    with Image.open(io.BytesIO(fast_overlay_png(result, m, m, max_side=800))) as im:
        assert max(im.size) <= 1000  # 800 for the map part, the legend below it
        rgb = np.asarray(im.convert("RGB")).astype(int)
    grey = np.nonzero(np.all(rgb == 232, axis=2).any(axis=1))[0]  # the map part's rows
    part = rgb[grey.min() : grey.max() + 1]
    assert len(part) <= 800
    colour = np.round(np.asarray(partition_style(0)[0]) * 255).astype(int)
    wall = np.all(part == colour, axis=2)
    rows = np.nonzero(wall.any(axis=1))[0]
    assert len(rows) >= 1 and rows.max() - rows.min() <= 4  # the thin wall, visible
    assert wall[rows[0]].sum() > 0.9 * (4800 / 8)  # along the whole wall


def test_save_results_overlay_kinds(tmp_path):
    m, ref, result = _case()
    fast = save_results(tmp_path / "fast.zip", result, m, ref, overlay="fast")
    none = save_results(tmp_path / "none.zip", result, m, ref, overlay="none")
    with zipfile.ZipFile(tmp_path / "none.zip") as zf:
        assert "overlay.png" not in zf.namelist()
    with zipfile.ZipFile(tmp_path / "fast.zip") as zf:
        assert zf.read("overlay.png") == fast.overlay_png
    back = load_results(tmp_path / "none.zip")
    assert back.overlay_png == b"" and none.overlay_png == b""
    assert back.info["overlay"] == "none" and fast.info["overlay"] == "fast"
    assert back.stats == none.stats
    with pytest.raises(ParameterError, match="overlay must be one of"):
        save_results(tmp_path / "x.zip", result, m, ref, overlay="svg")
    assert not (tmp_path / "x.zip").exists()


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    from test_report_fixtures import rooms

    folder = tmp_path_factory.mktemp("pair")
    brokenness.save_map(rooms(), folder / "ref.yaml")
    brokenness.save_map(rooms(), folder / "map.yaml")
    (folder / "manifest.csv").write_text("map,reference\nmap.yaml,ref.yaml\n")
    return folder


def _members(folder):
    (zip_path,) = folder.glob("*.zip")
    with zipfile.ZipFile(zip_path) as zf:
        return set(zf.namelist()), load_results(zip_path)


@pytest.mark.parametrize("workers", [1, 2])
def test_batch_writes_fast_overlays_by_default_and_none_writes_none(pair, tmp_path, workers):
    run_batch(pair / "manifest.csv", tmp_path / "d", workers=workers, progress=False)
    names, record = _members(tmp_path / "d")
    assert "overlay.png" in names and record.info["overlay"] == "fast"
    with Image.open(io.BytesIO(record.overlay_png)) as im:
        assert im.format == "PNG"
    summary = run_batch(
        pair / "manifest.csv", tmp_path / "n", workers=workers, progress=False, overlays="none"
    )
    assert summary.rows[0].status == "done"
    names, record = _members(tmp_path / "n")
    assert "overlay.png" not in names and record.overlay_png == b""
    assert list((tmp_path / "n").glob("*.png")) == []


def test_cli_overlays_and_yaml_manifest(pair, tmp_path, monkeypatch):
    if "batch" not in cli_main.SUBCOMMANDS:
        monkeypatch.setattr(cli_main, "SUBCOMMANDS", (*cli_main.SUBCOMMANDS, "batch"))
    doc = {"overlays": "figure", "pairs": [{"map": "map.yaml", "reference": "ref.yaml"}]}
    manifest = pair / "figure.yaml"
    manifest.write_text(yaml.safe_dump(doc))
    assert read_manifest(manifest).overlays == "figure"
    run_batch(manifest, tmp_path / "f", workers=1, progress=False)
    assert _members(tmp_path / "f")[1].info["overlay"] == "figure"
    # the command line wins over the manifest
    code = cli_main.main(
        ["batch", str(manifest), "--out", str(tmp_path / "c"), "--overlays", "none", "-q"]
    )
    assert code == 0
    names, record = _members(tmp_path / "c")
    assert "overlay.png" not in names and record.info["overlay"] == "none"
    bad = pair / "bad.yaml"
    bad.write_text(yaml.safe_dump({**doc, "overlays": "pdf"}))
    with pytest.raises(ManifestError, match="overlays must be one of"):
        read_manifest(bad)


def test_a_batch_worker_does_not_load_matplotlib():
    code = (
        "import sys, brokenness.batch.runner, brokenness.report.fast_overlay, "
        "brokenness.report.results; print('matplotlib' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_workers_get_one_blas_thread_and_the_parent_keeps_its_environment(monkeypatch):
    import concurrent.futures as cf

    from brokenness._threads import THREAD_ENV_VARS, forkserver_context, single_threaded_children

    for name in THREAD_ENV_VARS:
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("MKL_NUM_THREADS", "3")  # a user's own setting is left alone
    with single_threaded_children():
        assert os.environ["OPENBLAS_NUM_THREADS"] == "1"
        assert os.environ["MKL_NUM_THREADS"] == "3"
    assert "OPENBLAS_NUM_THREADS" not in os.environ
    ctx = forkserver_context()
    with cf.ProcessPoolExecutor(1, mp_context=ctx) as pool:
        assert pool.submit(os.getenv, "OPENBLAS_NUM_THREADS").result() == "1"
        assert pool.submit(os.getenv, "OMP_NUM_THREADS").result() == "1"
    assert "OPENBLAS_NUM_THREADS" not in os.environ


def test_a_bad_worker_memory_is_refused_before_any_work(pair, tmp_path, monkeypatch):
    monkeypatch.setenv("BROKENNESS_WORKER_MEMORY", "lots")
    with pytest.raises(ParameterError, match="BROKENNESS_WORKER_MEMORY"):
        run_batch(pair / "manifest.csv", tmp_path / "o", workers=2, progress=False)
    assert not list((tmp_path / "o").glob("*.zip"))
