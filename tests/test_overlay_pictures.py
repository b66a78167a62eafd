"""Overlay pictures a paper can print: big maps, many partitions, crop, metres, split."""

from __future__ import annotations

import time
import tracemalloc

import numpy as np
import pytest
from PIL import Image

from brokenness import OccupancyMap, RigidTransform
from brokenness.cli.main import main
from brokenness.errors import ParameterError
from brokenness.measure.result import BrokennessResult, Partition
from brokenness.report.overlay import (
    N_COLOURS,
    overlay_figure,
    overlay_raster,
    partition_style,
    render_overlay,
)


def grid_case(n: int, parts: int, *, resolution: float | None = 0.05, explored: float = 0.8):
    """A map of rooms (one-cell walls) in the middle ``explored`` share of an n x n grid,
    cut into ``parts`` partitions by blocks; the reference is the map itself."""
    states = np.full((n, n), -1, np.int8)
    lo, hi = int(n * (1 - explored) / 2), int(n * (1 + explored) / 2)
    states[lo:hi, lo:hi] = 0
    step = max(4, (hi - lo) // 16)
    for c in range(lo, hi, step):
        states[lo:hi, c] = 1
        states[c, lo:hi] = 1
    labels = np.full((n, n), -1, np.int16)
    rr, cc = np.nonzero(states == 1)
    side = int(np.ceil(np.sqrt(parts)))
    lab = np.minimum(
        ((rr - lo) * side // (hi - lo)) * side + (cc - lo) * side // (hi - lo), parts - 1
    )
    labels[rr, cc] = lab
    counts = [int((lab == i).sum()) for i in range(parts)]
    total = len(rr)
    ps = tuple(
        Partition(
            i,
            counts[i],
            counts[i] / total,
            RigidTransform(0.0, 0.0, 0.0),
            0.9,
            0.0,
            float(i),
            0.05 * i if resolution else None,
            0.0,
        )
        for i in range(parts)
    )
    m = OccupancyMap(states, resolution, (0.0, 0.0, 0.0) if resolution else None)
    return m, BrokennessResult(parts - 1, ps, labels, total, 0, "ifmi", {}, 0.0)


def test_sixteen_partitions_have_distinct_styles_and_matching_swatches():
    styles = {
        (tuple(np.round(partition_style(i)[0], 3)), partition_style(i)[1] > 0) for i in range(16)
    }
    assert len(styles) == 16 and N_COLOURS >= 10
    m, result = grid_case(400, 16)
    fig = overlay_figure(result, m, m)
    handles = fig.legends[0].legend_handles[:16]
    for i, h in enumerate(handles):
        rgb, stripes = partition_style(i)
        np.testing.assert_allclose(h.get_facecolor()[:3], rgb, atol=1e-6)
        assert bool(h.get_hatch()) == bool(stripes)
    # every partition's colour is in the raster, striped ones with their dark shade too
    rgb, _ = overlay_raster(result, m, m, target=800)
    flat = np.round(rgb.reshape(-1, 3) * 255).astype(int)
    present = {tuple(c) for c in np.unique(flat, axis=0)}
    for i in range(16):
        colour, stripes = partition_style(i)
        assert tuple(np.round(np.asarray(colour) * 255).astype(int)) in present, i
        if stripes:
            dark = tuple(np.round(np.asarray(colour) * 0.35 * 255).astype(int))
            assert dark in present, i


def test_one_cell_walls_stay_visible_on_a_big_map(monkeypatch):
    from brokenness.report import raster

    m, result = grid_case(4000, 2)
    colour = np.asarray(partition_style(0)[0], np.float32)

    def wall_share() -> float:
        rgb, view = overlay_raster(result, m, m, target=1000)
        assert max(rgb.shape[:2]) <= 1100 and view.k >= 3
        return float(np.mean(np.all(np.abs(rgb - colour) < 1e-3, axis=2)))

    widened = wall_share()
    monkeypatch.setattr(raster, "_wall_radius", lambda *args: 0)
    bare = wall_share()  # one-pixel lines: what a pooled picture would show
    assert widened > 2.5 * bare and widened > 0.02


def test_big_sparse_map_renders_quickly_in_little_memory(tmp_path):
    m, result = grid_case(10_000, 16, explored=0.5)
    tracemalloc.start()
    try:
        start = time.perf_counter()
        rgb, view = overlay_raster(result, m, m, target=1100)
        seconds = time.perf_counter() - start
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert seconds < 60  # loose: about 1-2 s here on an idle machine
    assert peak < 0.5 * m.states.size  # under half a byte per cell beyond the inputs
    # cropped to the explored half (plus a small margin)
    assert view.w * view.k < 0.6 * 10_000 and view.x0 > 2000
    out = tmp_path / "big.png"
    render_overlay(result, m, m, out, dpi=100)
    with Image.open(out) as im:
        assert im.size[0] < 1200


def test_axes_in_metres_only_with_a_resolution():
    m, result = grid_case(200, 3)
    ax = overlay_figure(result, m, m).axes[0]
    assert ax.get_xlabel().startswith("x (m")
    left, right = ax.get_xlim()
    assert 0.5 < left < right < 10.0  # metres of the explored box, not cells (0..200)
    bare, result = grid_case(200, 3, resolution=None)
    fig = overlay_figure(result, bare, bare)
    assert fig.axes[0].get_xlabel().startswith("column")
    texts = [t.get_text() for t in fig.legends[0].get_texts()]
    assert not any(" m" in t.split(",")[-1] for t in texts if "off" in t)
    assert any("cells" in t.split(",")[-1] for t in texts if "off" in t)


def test_split_mode_two_panels_in_both_frames(tmp_path):
    m, result = grid_case(300, 2)
    moved = RigidTransform(np.deg2rad(10.0), 40.0, -20.0)
    p1 = result.partitions[1]
    parts = (
        result.partitions[0],
        Partition(1, p1.cells, p1.fraction, moved, 0.9, 10.0, 45.0, 2.2, 0.0),
    )
    result = BrokennessResult(1, parts, result.labels, result.occupied_cells, 0, "ifmi", {}, 0.0)
    fig = overlay_figure(result, m, m, mode="split", title="two panels")
    assert len(fig.axes) == 2 and fig._suptitle.get_text() == "two panels"
    assert "reference frame" in fig.axes[1].get_xlabel()
    # the moved partition reaches beyond the reference: the right panel holds it all
    assert fig.axes[1].get_xlim()[1] > fig.axes[0].get_xlim()[1]
    with pytest.raises(ParameterError, match="overlay mode"):
        overlay_figure(result, m, m, mode="three")


def test_cli_overlay_options(tmp_path, capsys):
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    out = tmp_path / "o.png"
    args = [
        "compute",
        str(root / "examples" / "broken_building_31.yaml"),
        str(root / "examples" / "building_31.yaml"),
        "-q",
        "--overlay",
        str(out),
    ]
    assert main([*args, "--overlay-mode", "split", "--dpi", "60", "--title", "T"]) == 0
    with Image.open(out) as im:
        small = im.size
    assert main([*args, "--dpi", "120"]) == 0
    with Image.open(out) as im:
        assert im.size[0] > small[0]
    assert main([*args, "--dpi", "0"]) == 2


def test_an_overlay_replaces_its_file_only_once_written_whole(tmp_path, monkeypatch):
    """The PNG is written to a temporary file beside the target, which replaces it at the
    end: a failure half-way leaves the earlier picture as it was, and no temporary file."""
    from matplotlib.figure import Figure

    m, result = grid_case(120, 2)
    out = tmp_path / "overlay.png"
    render_overlay(result, m, m, out, dpi=50)
    before = out.read_bytes()
    assert before.startswith(b"\x89PNG")

    def broken(self, fname, **kwargs):  # noqa: ANN001, ANN003 - matplotlib's signature
        with open(fname, "wb") as fh:
            fh.write(b"half a picture")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(Figure, "savefig", broken)
    with pytest.raises(OSError):
        render_overlay(result, m, m, out, dpi=50)
    assert out.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["overlay.png"]
