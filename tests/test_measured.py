"""The "not measured" contract: no degree for a map that the evidence does not place on the
reference, through the API, the command line, a batch and ``compare``."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

import brokenness
import brokenness.cli.main as cli_main
from brokenness.batch import PairOptions, run_batch
from brokenness.batch.runner import STATUS_DONE, STATUS_NOT_MEASURED
from brokenness.report import collect_results, group_table, load_results


def _room() -> np.ndarray:
    room = np.zeros((80, 80), bool)
    room[10, 10:70] = room[70, 10:70] = room[10:70, 10] = room[10:70, 70] = True
    room[10:40, 40] = True
    return room


def _dots() -> np.ndarray:
    dots = np.zeros((80, 80), bool)
    dots[np.random.default_rng(0).random((80, 80)) < 0.01] = True
    return dots


@pytest.fixture()
def maps(tmp_path):
    brokenness.save_map(
        brokenness.OccupancyMap.from_array(_room(), resolution=0.05), tmp_path / "room.yaml"
    )
    brokenness.save_map(
        brokenness.OccupancyMap.from_array(_dots(), resolution=0.05), tmp_path / "dots.yaml"
    )
    return tmp_path


def test_api_not_measured_has_no_degree():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", brokenness.NothingFoundWarning)
        result = brokenness.compute_brokenness(_dots(), _room())
    assert result.measured is False and result.degree is None and result.reason
    record = result.to_dict()
    assert record["degree"] is None and record["measured"] is False
    assert json.loads(json.dumps(record))["reason"] == result.reason
    same = brokenness.compute_brokenness(_room(), _room())
    assert same.measured is True and same.degree == 0 and same.reason is None


def test_cli_exit_status_and_json(maps, capsys):
    code = cli_main.main(["compute", str(maps / "dots.yaml"), str(maps / "room.yaml")])
    out = capsys.readouterr()
    assert code == cli_main.EXIT_NOT_MEASURED == 3
    assert "not measured" in out.out and "warning" not in out.err
    code = cli_main.main(
        ["compute", str(maps / "dots.yaml"), str(maps / "room.yaml"), "--json", "-"]
    )
    record = json.loads(capsys.readouterr().out)
    assert code == 3 and record["degree"] is None and record["measured"] is False
    code = cli_main.main(["compute", str(maps / "room.yaml"), str(maps / "room.yaml")])
    assert code == 0 and "degree of brokenness: 0" in capsys.readouterr().out


def test_batch_and_compare_keep_not_measured_apart(maps, tmp_path):
    manifest = tmp_path / "runs.csv"
    manifest.write_text(
        "map,reference,system\n"
        f"{maps / 'dots.yaml'},{maps / 'room.yaml'},a\n"
        f"{maps / 'room.yaml'},{maps / 'room.yaml'},a\n"
    )
    out = tmp_path / "out"
    summary = run_batch(manifest, out, workers=1, options=PairOptions(), progress=False)
    statuses = sorted(r.status for r in summary.rows)
    assert statuses == sorted([STATUS_DONE, STATUS_NOT_MEASURED])
    row = next(r for r in summary.rows if r.status == STATUS_NOT_MEASURED)
    assert row.degree is None
    assert "1 done, 1 not measured" in summary.markdown_path.read_text()
    record = load_results(out / row.result)
    assert record.measured is False and record.degree is None

    table = group_table(collect_results([out]), ["system"])
    (group,) = table.rows
    assert group.results == 1 and group.not_measured == 1 and group.failed == 0
    assert group.mean_degree == 0.0  # the unmeasured pair is not averaged in as a 0
