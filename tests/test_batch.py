"""Batch runs: real maps in a temporary folder, a process pool, a real Dask cluster, the CLI."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from _breaking import break_map, move_about, strips
from test_report_fixtures import rooms

import brokenness
import brokenness.cli.main as cli_main
from brokenness import RigidTransform
from brokenness.batch import ManifestError, PairOptions, read_manifest, run_batch
from brokenness.report import load_results

FAST = PairOptions(dpi=30)  # small overlays: the pictures are not what these tests check

# (map file, system, noise, expected degree); None = the file does not exist
CASES = [
    ("ref_copy.yaml", "alpha", "0.0", 0),
    ("alpha_0.1.yaml", "alpha", "0.1", 1),
    ("beta_0.0.yaml", "beta", "0.0", 0),
    ("beta_0.2.yaml", "beta", "0.2", 1),
    ("missing.yaml", "beta", "0.3", None),
]


@pytest.fixture(scope="module")
def maps(tmp_path_factory) -> Path:
    """ref.yaml, maps of degree 0 and 1 (80x80 and 100x100 cells), and manifest.csv."""
    folder = tmp_path_factory.mktemp("maps")
    ref = rooms()
    brokenness.save_map(ref, folder / "ref.yaml")
    brokenness.save_map(ref, folder / "ref_copy.yaml")
    brokenness.save_map(ref, folder / "beta_0.0.yaml")
    halves = strips(ref.shape, [0.5])
    for name, motion in [
        ("alpha_0.1.yaml", move_about((60, 40), 15, (8, 5))),
        ("beta_0.2.yaml", RigidTransform(0.0, 12, 8)),
    ]:
        broken, _ = break_map(ref, halves, [RigidTransform.identity(), motion], pad=10)
        brokenness.save_map(broken, folder / name)
    lines = ["map,reference,system,noise"]
    lines += [f"{name},ref.yaml,{system},{noise}" for name, system, noise, _ in CASES]
    (folder / "manifest.csv").write_text("\n".join(lines) + "\n")
    return folder


def by_map(summary):
    return {r.map: r for r in summary.rows}


def test_pool_error_row_resume_and_summary(maps, tmp_path):
    out = tmp_path / "out"
    summary = run_batch(maps / "manifest.csv", out, workers=2, progress=False, options=FAST)
    rows = by_map(summary)
    for name, system, noise, degree in CASES:
        row = rows[name]
        assert row.labels == {"system": system, "noise": noise}
        if degree is None:
            assert row.status == "error" and "no such file" in row.error
            assert row.result is None and row.degree is None
            err = json.loads((out / f"{Path(name).stem}-{row.id}.error.json").read_text())
            assert err["labels"] == {"system": system, "noise": noise}
            assert "no such file" in err["error"]
        else:
            assert row.status == "done" and row.error is None
            assert row.degree == degree
            record = load_results(out / row.result)
            assert record.degree == degree
            assert record.run_labels == {"system": system, "noise": noise}
            assert record.info["pair"]["map"] == name
            assert record.info["inputs"]["map"]["sha256"]
    assert summary.count("done") == 4 and summary.count("error") == 1

    # summary.csv: one row per pair, labels as columns, numbers parse back
    with open(out / "summary.csv", newline="") as fh:
        table = list(csv.DictReader(fh))
    assert [r["map"] for r in table] == [c[0] for c in CASES]
    for r, (_, system, noise, degree) in zip(table, CASES, strict=True):
        assert (r["system"], r["noise"]) == (system, noise)
        assert r["degree"] == ("" if degree is None else str(degree))
        if degree is not None:
            assert 0.5 < float(r["largest_fraction"]) <= 1.0
    md = (out / "summary.md").read_text().splitlines()
    assert md[0] == "5 pairs: 4 done, 0 not measured, 0 skipped (done before), 1 failed"
    assert md[2].startswith("| id | status | resumed | map | reference | system | noise | degree |")
    assert len([ln for ln in md if ln.startswith("| ")]) == 6  # header + 5 rows

    # resume: nothing done is evaluated again (files untouched), the failed pair is retried
    zips = sorted(out.glob("*.zip"))
    stamps = {p: p.stat().st_mtime_ns for p in zips}
    calls = []
    import brokenness.measure as measure

    real = measure.compute_brokenness

    def counting(*args, **kwargs):
        calls.append(1)
        return real(*args, **kwargs)

    mp = pytest.MonkeyPatch()
    mp.setattr(measure, "compute_brokenness", counting)
    try:
        again = run_batch(maps / "manifest.csv", out, workers=1, progress=False, options=FAST)
        assert calls == []  # the missing map fails while loading, before computing
        assert {p: p.stat().st_mtime_ns for p in zips} == stamps
        assert again.count("skipped") == 4 and again.count("error") == 1
        assert [r.degree for r in again.rows] == [r.degree for r in summary.rows]
        # a resumed row keeps its status (done / not measured), marked as resumed
        assert [r.status for r in again.rows] == [r.status for r in summary.rows]
        assert [r.resumed for r in again.rows] == [r.status != "error" for r in summary.rows]
        with open(out / "summary.csv", newline="") as fh:
            assert {r["status"] for r in csv.DictReader(fh)} <= {"done", "error"}
        # a lost and a damaged result are evaluated again, the rest still skipped
        zips[0].unlink()
        zips[1].write_bytes(b"PK\x03\x04 damaged")
        third = run_batch(maps / "manifest.csv", out, workers=1, progress=False, options=FAST)
        assert len(calls) == 2
        assert third.count("done") == 2 and third.count("skipped") == 2
        assert load_results(zips[1]).degree in (0, 1)
    finally:
        mp.undo()
    assert (out / "summary.md").read_text().startswith("5 pairs: 2 done, 0 not measured, 2 skipped")


def test_yaml_manifest_and_options(maps, tmp_path):
    doc = {
        "defaults": {"reference": "ref.yaml", "dataset": "rooms"},
        "options": {"threshold": 3.0},
        "pairs": [{"map": "alpha_0.1.yaml", "system": "alpha", "noise": 0.1}],
    }
    import yaml

    manifest = maps / "m.yaml"
    manifest.write_text(yaml.safe_dump(doc))
    summary = run_batch(manifest, tmp_path, workers=1, progress=False, options=FAST)
    (row,) = summary.rows
    assert row.status == "done" and row.labels == {
        "dataset": "rooms",
        "system": "alpha",
        "noise": "0.1",
    }
    record = load_results(tmp_path / row.result)
    assert record.info["parameters"]["threshold"] == 3.0


def test_real_dask_cluster_on_loopback(maps, tmp_path):
    distributed = pytest.importorskip("distributed")
    pool_out, dask_out = tmp_path / "pool", tmp_path / "dask"
    manifest = read_manifest(maps / "manifest.csv")
    with distributed.LocalCluster(
        n_workers=1,
        threads_per_worker=1,
        processes=False,
        protocol="tcp",  # real TCP over loopback, not the in-process transport
        host="127.0.0.1",
        dashboard_address=None,
        silence_logs="error",
    ) as cluster:
        assert cluster.scheduler_address.startswith("tcp://127.0.0.1:")
        summary = run_batch(
            manifest, dask_out, scheduler=cluster.scheduler_address, progress=False, options=FAST
        )
    assert summary.count("done") == 4 and summary.count("error") == 1
    inline = run_batch(manifest, pool_out, workers=1, progress=False, options=FAST)
    # the same result files: deterministic figures equal bit for bit
    for a, b in zip(summary.rows, inline.rows, strict=True):
        assert (a.status, a.degree, a.result) == (b.status, b.degree, b.result)
        if a.result:
            ra, rb = load_results(dask_out / a.result), load_results(pool_out / b.result)
            assert ra.stats == rb.stats
            np.testing.assert_array_equal(ra.labels, rb.labels)


def test_batch_argument_errors(maps, tmp_path):
    with pytest.raises(brokenness.ParameterError, match="workers must be at least 1"):
        run_batch(maps / "manifest.csv", tmp_path, workers=0, progress=False, options=FAST)
    with pytest.raises(brokenness.ParameterError, match="not both"):
        run_batch(maps / "manifest.csv", tmp_path, scheduler="tcp://x:1", local_cluster=True)
    bad = tmp_path / "bad.csv"
    bad.write_text("map,ref\na.pgm,b.pgm\n")
    with pytest.raises(ManifestError, match="'reference'"):
        run_batch(bad, tmp_path / "o", progress=False, options=FAST)
    assert not (tmp_path / "o").exists()


# -- the command line -------------------------------------------------------------------------
@pytest.fixture
def cli(monkeypatch):
    """``brokenness ...`` through the real main(), with batch registered."""
    if "batch" not in cli_main.SUBCOMMANDS:
        monkeypatch.setattr(cli_main, "SUBCOMMANDS", (*cli_main.SUBCOMMANDS, "batch"))
    return cli_main.main


def test_cli_batch_exit_codes(cli, maps, tmp_path, capsys):
    out = tmp_path / "out"
    code = cli(
        [
            "batch",
            str(maps / "manifest.csv"),
            "--out",
            str(out),
            "--workers",
            "1",
            "--no-progress",
            "--method",
            "ifmi",
        ]
    )
    stdout = capsys.readouterr().out
    assert code == 1  # ran to the end, one pair failed
    assert "5 pairs: 4 evaluated, 0 not measured, 0 already done, 1 failed" in stdout
    assert "missing.yaml" in stdout and "summary.csv" in stdout
    assert len(list(out.glob("*.zip"))) == 4

    good = tmp_path / "good.csv"
    good.write_text(f"map,reference,system\n{maps / 'beta_0.2.yaml'},{maps / 'ref.yaml'},beta\n")
    code = cli(["batch", str(good), "--out", str(out), "--no-progress", "--threshold", "2"])
    assert code == 0
    assert (
        "1 pair: 1 evaluated, 0 not measured, 0 already done, 0 failed" in capsys.readouterr().out
    )
    assert cli(["batch", str(good), "--out", str(out), "--no-progress"]) == 0
    assert "1 already done" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("map,reference\n", "lists no pairs"),
        ("map,reference\na.pgm,b.pgm,extra\n", "more values than columns"),
        (None, "no such manifest file"),
    ],
)
def test_cli_bad_manifest_exit_2(cli, tmp_path, capsys, content, message):
    manifest = tmp_path / "m.csv"
    if content is not None:
        manifest.write_text(content)
    code = cli(["batch", str(manifest), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 2 and message in err and err.count("\n") == 1
    assert not (tmp_path / "o").exists()


def test_cli_local_cluster(cli, maps, tmp_path, capsys):
    pytest.importorskip("distributed")
    good = tmp_path / "good.csv"
    good.write_text(f"map,reference\n{maps / 'alpha_0.1.yaml'},{maps / 'ref.yaml'}\n")
    code = cli(
        [
            "batch",
            str(good),
            "--out",
            str(tmp_path / "o"),
            "--local-cluster",
            "--workers",
            "1",
            "--no-progress",
        ]
    )
    assert code == 0, capsys.readouterr()
    (zipped,) = (tmp_path / "o").glob("*.zip")
    assert load_results(zipped).degree == 1


def test_cli_scheduler_and_local_cluster_exclusive(cli, maps, tmp_path, capsys):
    with pytest.raises(SystemExit) as info:
        cli(
            [
                "batch",
                str(maps / "manifest.csv"),
                "--out",
                str(tmp_path),
                "--scheduler",
                "tcp://127.0.0.1:1",
                "--local-cluster",
            ]
        )
    assert info.value.code == 2
    assert "not allowed with argument" in capsys.readouterr().err


def test_unreachable_scheduler_is_one_line(maps, tmp_path):
    pytest.importorskip("distributed")
    with pytest.raises(brokenness.ParameterError) as info:
        run_batch(
            maps / "manifest.csv",
            tmp_path,
            scheduler="tcp://127.0.0.1:9",
            progress=False,
            connect_timeout=0.5,
        )
    assert str(info.value).startswith("cannot connect to the Dask scheduler at tcp://127.0.0.1:9")
    assert "\n" not in str(info.value)
    assert not list(tmp_path.glob("*.zip"))


def test_without_distributed_a_cluster_batch_says_what_to_install(
    cli, maps, tmp_path, capsys, hide_package
):
    """Without the optional packages, a batch on a Dask cluster stops before any output with
    a MissingDependencyError naming the extra (one line, status 2 on the command line)."""
    hide_package("distributed")
    with pytest.raises(brokenness.MissingDependencyError, match=r"brokenness\[dask\]"):
        run_batch(maps / "manifest.csv", tmp_path / "o", local_cluster=True, progress=False)
    assert not (tmp_path / "o").exists()
    capsys.readouterr()
    args = ["batch", str(maps / "manifest.csv"), "--out", str(tmp_path / "c")]
    assert cli([*args, "--local-cluster"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "pip install 'brokenness[dask]'" in err
