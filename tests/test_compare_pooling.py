"""compare keeps results computed differently apart; compute --label; s.d./min/max."""

from __future__ import annotations

import csv
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from brokenness.cli.main import main
from brokenness.report.collect import collect_results
from brokenness.report.tables import group_table

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "broken_building_31.yaml"
REFERENCE = ROOT / "examples" / "building_31.yaml"


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("runs")
    for name, pair, extra in [
        ("a", (EXAMPLE, REFERENCE), ["--label", "system=x", "--label", "expected_degree=2"]),
        ("b", (REFERENCE, REFERENCE), ["--label", "system=x", "--label", "expected_degree=0"]),
        ("c", (EXAMPLE, REFERENCE), ["--label", "system=x", "--threshold", "3"]),
    ]:
        args = ["compute", str(pair[0]), str(pair[1]), "-q", *extra]
        assert main([*args, "--save-results", str(out / f"{name}.zip")]) == 0
    return out


def test_labels_stored_like_a_manifest(runs):
    entries = {e.path.stem: e for e in collect_results([runs])}
    assert entries["a"].labels == {"system": "x", "expected_degree": "2"}
    assert entries["c"].labels == {"system": "x"}
    assert entries["c"].parameters["threshold"] == 3.0


def test_bad_label_is_bad_input(capsys):
    assert main(["compute", str(REFERENCE), str(REFERENCE), "--label", "novalue"]) == 2
    assert "KEY=VALUE" in capsys.readouterr().err


def test_different_parameters_are_not_pooled(runs):
    entries = collect_results([runs])
    table = group_table(entries, ["system"])
    assert table.group_by == ("system", "parameters")
    recs = table.records()
    assert [r["results"] for r in recs] == [2, 1]
    assert "; threshold=2.0" in recs[0]["parameters"]
    assert "; threshold=3.0" in recs[1]["parameters"]
    assert (recs[0]["min_degree"], recs[0]["max_degree"]) == (0, 2)
    assert recs[0]["sd_degree"] == pytest.approx(2**0.5)
    assert recs[1]["sd_degree"] is None
    pooled = group_table(entries, ["system"], pool=True)
    assert pooled.group_by == ("system",) and pooled.records()[0]["results"] == 3


def test_cli_compare_piped_is_never_cut(runs, tmp_path):
    table = tmp_path / "t.csv"
    done = subprocess.run(
        [sys.executable, "-m", "brokenness.cli.main", "compare", str(runs), "--table", str(table)],
        capture_output=True,
        text=True,
        check=True,
        env={"COLUMNS": "40", "PATH": ""},
    )
    assert "…" not in done.stdout and "threshold=3.0" in done.stdout
    assert "3 results, 0 failures" in done.stdout
    rows = list(csv.DictReader(table.open()))
    assert {"sd_degree", "min_degree", "max_degree", "parameters"} <= set(rows[0])
    quiet = [sys.executable, "-m", "brokenness.cli.main", "compare", str(runs), "-q"]
    assert subprocess.run(quiet, capture_output=True, text=True, check=True).stdout == ""


def test_plot_has_expected_degree_line_and_n_per_point(runs):
    from brokenness.report.plots import comparison_figure

    entries = collect_results([runs])
    fig = comparison_figure(entries)
    assert len(fig.axes) == 2  # found vs expected, partition sizes
    ax = fig.axes[0]
    assert ax.get_xlabel() == "expected_degree"
    lines = [line for line in ax.get_lines() if line.get_label() == "y = x"]
    assert len(lines) == 1
    np.testing.assert_allclose(lines[0].get_xdata(), lines[0].get_ydata())
    notes = sorted(t.get_text() for t in ax.texts)
    assert notes == ["n=1", "n=1"]
    # without expected degrees, no such panel
    plain = [e for e in entries if "expected_degree" not in e.labels]
    assert len(comparison_figure(plain).axes) == 1
    # one expected degree only: the line still has a length (it is drawn, not a point)
    one = [e for e in entries if "expected_degree" in e.labels]
    one = [e for e in one if e.labels["expected_degree"] == one[0].labels["expected_degree"]]
    (line,) = [ln for ln in comparison_figure(one).axes[0].get_lines() if ln.get_label() == "y = x"]
    assert np.ptp(line.get_xdata()) > 0


def test_cli_compare_plot_file(runs, tmp_path):
    out = tmp_path / "p.png"
    assert main(["compare", str(runs), "--plot", str(out), "--dpi", "50", "-q"]) == 0
    assert out.read_bytes()[:4] == b"\x89PNG"


def test_results_overlay_picks_the_picture_in_the_zip(tmp_path):
    """compute --results-overlay: the zip's overlay.png is the matplotlib figure by default,
    the batch's raster picture with ``fast`` (the same bytes as fast_overlay_png) and absent
    with ``none``; the result itself is the same."""
    from brokenness import compute_brokenness, load_map
    from brokenness.report.fast_overlay import fast_overlay_png
    from brokenness.report.results import load_results

    records = {}
    for kind in ("figure", "fast", "none"):
        zip_path = tmp_path / f"{kind}.zip"
        args = ["compute", str(EXAMPLE), str(REFERENCE), "-q", "--save-results", str(zip_path)]
        extra = [] if kind == "figure" else ["--results-overlay", kind]
        assert main([*args, *extra]) == 0
        records[kind] = load_results(zip_path)
    m, ref = load_map(EXAMPLE), load_map(REFERENCE)
    assert records["fast"].overlay_png == fast_overlay_png(compute_brokenness(m, ref), m, ref)
    assert records["figure"].overlay_png.startswith(b"\x89PNG")
    assert records["figure"].overlay_png != records["fast"].overlay_png
    assert records["none"].overlay_png == b""
    assert len({r.stats["degree"] for r in records.values()}) == 1
