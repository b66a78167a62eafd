"""Comparison tables and plots from real result zips (small real computations)."""

from __future__ import annotations

import csv
import io
import zipfile
from pathlib import Path

import numpy as np
import pytest
from _breaking import break_map, move_about, strips
from PIL import Image
from test_report_fixtures import rooms

import brokenness
import brokenness.cli.main as cli_main
from brokenness import RigidTransform
from brokenness.batch import PairOptions, run_batch
from brokenness.errors import ParameterError
from brokenness.report import (
    ResultFileError,
    collect_results,
    comparison_figure,
    group_table,
    save_results,
    write_plot,
    write_table,
)
from brokenness.report.tables import table_csv, table_markdown

# system, noise, seed -> map file; degree 0 at noise 0, degree 1 otherwise
RUNS = [
    ("alpha", "0.0", "1", "ref_copy.yaml"),
    ("alpha", "0.0", "2", "ref_copy.yaml"),
    ("alpha", "0.2", "1", "rot.yaml"),
    ("beta", "0.0", "1", "ref_copy.yaml"),
    ("beta", "0.2", "1", "shift.yaml"),
    ("beta", "0.2", "2", "rot.yaml"),
    ("beta", "0.4", "1", "missing.yaml"),  # fails: an error file, counted as a failure
]


@pytest.fixture(scope="module")
def batch_dir(tmp_path_factory) -> Path:
    """A real batch output folder: 6 result zips and 1 error file."""
    folder = tmp_path_factory.mktemp("cmp")
    ref = rooms()
    brokenness.save_map(ref, folder / "ref.yaml")
    brokenness.save_map(ref, folder / "ref_copy.yaml")
    halves = strips(ref.shape, [0.5])
    for name, motion in [
        ("rot.yaml", move_about((60, 40), 15, (8, 5))),
        ("shift.yaml", RigidTransform(0.0, 12, 8)),
    ]:
        broken, _ = break_map(ref, halves, [RigidTransform.identity(), motion], pad=10)
        brokenness.save_map(broken, folder / name)
    lines = ["map,reference,system,noise,seed"]
    lines += [f"{m},ref.yaml,{s},{n},{seed}" for s, n, seed, m in RUNS]
    (folder / "runs.csv").write_text("\n".join(lines) + "\n")
    out = folder / "results"
    summary = run_batch(
        folder / "runs.csv", out, workers=1, progress=False, options=PairOptions(dpi=30)
    )
    assert [r.degree for r in summary.rows] == [0, 0, 1, 0, 1, 1, None]
    return out


def test_collect_folder_with_error_files(batch_dir):
    entries = collect_results([batch_dir])
    assert len(entries) == 7
    failed = [e for e in entries if e.failed]
    assert len(failed) == 1 and "no such file" in failed[0].error
    assert failed[0].labels == {"system": "beta", "noise": "0.4", "seed": "1"}
    ok = [e for e in entries if not e.failed]
    assert sorted(e.degree for e in ok) == [0, 0, 0, 1, 1, 1]
    for e in ok:
        assert abs(sum(e.partition_fractions) - 1.0) < 0.2
        assert e.partition_fractions == tuple(sorted(e.partition_fractions, reverse=True))
    # the same file twice (folder and file) counts once
    one = sorted(batch_dir.glob("*.zip"))[0]
    assert len(collect_results([batch_dir, one])) == 7


def test_grouped_table_figures(batch_dir):
    entries = collect_results([batch_dir])
    table = group_table(entries)  # default: every label except seed
    assert table.group_by == ("system", "noise")
    recs = table.records()
    keys = [(r["system"], r["noise"]) for r in recs]
    assert keys == [
        ("alpha", "0.0"),
        ("alpha", "0.2"),
        ("beta", "0.0"),
        ("beta", "0.2"),
        ("beta", "0.4"),
    ]
    a0, a2, b0, b2, b4 = recs
    assert (a0["results"], a0["failed"], a0["mean_degree"], a0["median_degree"]) == (2, 0, 0, 0)
    assert a0["mean_largest_fraction"] == pytest.approx(1.0)
    assert (a2["results"], a2["mean_degree"]) == (1, 1.0)
    assert (b2["results"], b2["mean_degree"], b2["median_degree"]) == (2, 1.0, 1.0)
    assert b2["mean_largest_fraction"] < 0.8
    assert (b4["results"], b4["failed"], b4["mean_degree"]) == (0, 1, None)
    # mean over the members, computed here from the entries themselves
    beta02 = [
        e for e in entries if e.labels.get("system") == "beta" and e.labels.get("noise") == "0.2"
    ]
    assert b2["mean_largest_fraction"] == pytest.approx(
        np.mean([e.largest_fraction for e in beta02])
    )
    assert b2["mean_psi_repaired"] == pytest.approx(np.mean([e.psi_repaired for e in beta02]))

    by_system = group_table(entries, ["system"]).records()
    assert [(r["system"], r["results"], r["failed"]) for r in by_system] == [
        ("alpha", 3, 0),
        ("beta", 3, 1),
    ]
    assert by_system[1]["mean_degree"] == pytest.approx(2 / 3)
    assert by_system[1]["median_degree"] == 1.0
    with pytest.raises(ParameterError, match="no result has the label 'dataset'"):
        group_table(entries, ["dataset"])


def test_csv_and_markdown_parse_back(batch_dir, tmp_path):
    table = group_table(collect_results([batch_dir]), ["system", "noise"])
    csv_path = write_table(table, tmp_path / "t.csv")
    with open(csv_path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0]) == table.columns
    for row, rec in zip(rows, table.records(), strict=True):
        assert row["system"] == rec["system"] and int(row["results"]) == rec["results"]
        if rec["mean_degree"] is None:
            assert row["mean_degree"] == ""
        else:
            assert float(row["mean_degree"]) == pytest.approx(rec["mean_degree"], rel=1e-9)
            assert float(row["mean_psi_map"]) == pytest.approx(rec["mean_psi_map"], rel=1e-9)
    assert csv_path.read_text() == table_csv(table)

    md = write_table(table, tmp_path / "t.md").read_text().splitlines()
    assert md == table_markdown(table).splitlines()
    header = [c.strip() for c in md[0].strip("|").split("|")]
    assert header == table.columns
    assert md[1].startswith("|---|---|---:|")
    body = [[c.strip() for c in ln.strip("|").split("|")] for ln in md[2:]]
    assert len(body) == 5
    assert body[1][:6] == ["alpha", "0.2", "1", "0", "0", "1.000"]
    with pytest.raises(ParameterError, match=r"\.csv or \.md"):
        write_table(table, tmp_path / "t.xlsx")


def test_plot_png_decodes(batch_dir, tmp_path):
    entries = collect_results([batch_dir])
    fig = comparison_figure(entries)
    assert len(fig.axes) == 2
    degree_ax, sizes_ax = fig.axes
    assert degree_ax.get_xlabel() == "noise" and "partition size" in sizes_ax.get_xlabel()
    assert [t.get_text() for t in degree_ax.get_legend().get_texts()] == ["alpha", "beta"]
    path = write_plot(entries, tmp_path / "cmp.png", dpi=80)
    img = Image.open(path)
    img.load()
    assert img.format == "PNG" and img.width > 400 and img.height > 200
    pixels = np.asarray(img.convert("RGB"))
    assert len(np.unique(pixels.reshape(-1, 3), axis=0)) > 20  # not a blank canvas
    # another series label, the failure left out by the caller
    ok = [e for e in entries if not e.failed]
    fig = comparison_figure(ok, series_label="seed")
    assert [t.get_text() for t in fig.axes[0].get_legend().get_texts()] == ["1", "2"]
    with pytest.raises(ParameterError, match="not a number"):
        comparison_figure(entries, x_label="system")
    with pytest.raises(ParameterError, match="must be written"):
        write_plot(entries, tmp_path / "cmp.docx")


def test_single_compute_result_without_labels(tmp_path):
    ref = rooms()
    result = brokenness.compute_brokenness(ref, ref)
    path = tmp_path / "one.zip"
    save_results(path, result, ref, ref, info={"command": "compute"}, dpi=60)
    (entry,) = collect_results([path])
    assert entry.labels == {} and entry.degree == 0
    table = group_table([entry])
    assert table.group_by == () and table.records()[0]["results"] == 1
    fig = comparison_figure([entry])
    assert len(fig.axes) == 1  # no noise label: partition sizes only


def test_bad_inputs(tmp_path):
    text = tmp_path / "notes.txt"
    text.write_text("hello")
    corrupt = tmp_path / "cut.zip"
    corrupt.write_bytes(b"PK\x03\x04" + b"\x00" * 40)
    other = tmp_path / "other.zip"
    with zipfile.ZipFile(other, "w") as zf:
        zf.writestr("readme.txt", "not a result")
    empty = tmp_path / "empty"
    empty.mkdir()
    cases = [
        (text, "not a result zip"),
        (corrupt, "not a valid zip file"),
        (other, "not a brokenness result file"),
        (empty, "no result files"),
        (tmp_path / "nope.zip", "no such result file"),
    ]
    for path, message in cases:
        with pytest.raises(ResultFileError, match=message):
            collect_results([path])


# -- the command line -------------------------------------------------------------------------
@pytest.fixture
def cli(monkeypatch):
    if "compare" not in cli_main.SUBCOMMANDS:
        monkeypatch.setattr(cli_main, "SUBCOMMANDS", (*cli_main.SUBCOMMANDS, "compare"))
    return cli_main.main


def test_cli_compare(cli, batch_dir, tmp_path, capsys):
    table, plot = tmp_path / "t.md", tmp_path / "p.png"
    code = cli(
        [
            "compare",
            str(batch_dir),
            "--group-by",
            "system",
            "--table",
            str(table),
            "--plot",
            str(plot),
            "--dpi",
            "60",
        ]
    )
    out = capsys.readouterr().out
    assert code == 0
    assert "6 result(s), 1 failure(s)" in out and "alpha" in out and "beta" in out
    assert table.read_text().startswith("| system | results | not_measured | failed |")
    assert Image.open(io.BytesIO(plot.read_bytes())).format == "PNG"


def test_cli_compare_bad_input_exit_2(cli, batch_dir, tmp_path, capsys):
    empty = tmp_path / "empty"
    empty.mkdir()
    corrupt = tmp_path / "bad.zip"
    corrupt.write_bytes(b"garbage")
    for args, message in [
        ([str(empty)], "no result files"),
        ([str(corrupt)], "not a valid zip file"),
        ([str(batch_dir), "--table", str(tmp_path / "t.txt")], ".csv or .md"),
        ([str(batch_dir), "--group-by", "colour"], "no result has the label 'colour'"),
    ]:
        code = cli(["compare", *args])
        err = capsys.readouterr().err
        assert code == 2 and message in err and err.count("\n") == 1, (args, err)
    assert not (tmp_path / "t.txt").exists()
