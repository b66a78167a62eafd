"""``brokenness simulate`` through the real command line (synthetic and from a CARMEN log)."""

from __future__ import annotations

import json
from pathlib import Path

from brokenness import compute_brokenness, load_map
from brokenness.cli.main import main

LOG = Path(__file__).parent / "data" / "carmen" / "orebro-corrected.log.gz"


def test_simulate_writes_maps_and_truth(tmp_path, capsys):
    assert main(["simulate", "--out", str(tmp_path), "--degree", "1", "--seed", "3"]) == 0
    assert "expected degree 1" in capsys.readouterr().out
    truth = json.loads((tmp_path / "sim_0003.json").read_text())
    assert truth["expected_degree"] == 1
    m = load_map(tmp_path / "sim_0003.yaml")
    ref = load_map(tmp_path / "sim_0003_reference.yaml")
    assert compute_brokenness(m, ref).degree == 1


def test_simulate_from_a_carmen_log(tmp_path, capsys):
    args = ["simulate", "--out", str(tmp_path), "--log", str(LOG), "--degree", "1"]
    assert main([*args, "--resolution", "0.1"]) == 0
    truth = json.loads((tmp_path / "sim_0000.json").read_text())
    assert truth["expected_degree"] == 1
    m = load_map(tmp_path / "sim_0000.yaml")
    ref = load_map(tmp_path / "sim_0000_reference.yaml")
    assert m.resolution == ref.resolution == 0.1
    assert compute_brokenness(m, ref).degree == 1


def test_simulate_bad_log_is_one_line(tmp_path, capsys):
    not_a_log = tmp_path / "x.log"
    not_a_log.write_text("hello\nworld\n")
    assert main(["simulate", "--out", str(tmp_path), "--log", str(not_a_log)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "x.log" in err


def test_simulate_from_a_plan_of_the_users_building(tmp_path, capsys):
    """``--plan``: the Nav2 depot map toured by the simulated laser and broken twice."""
    plan = Path(__file__).parent / "data" / "depot.yaml"
    args = ["simulate", "--out", str(tmp_path), "--plan", str(plan), "--degree", "2"]
    assert main([*args, "--seed", "4", "--quiet"]) == 0
    truth = json.loads((tmp_path / "sim_0004.json").read_text())
    assert truth["expected_degree"] == 2 and truth["parameters"]["plan"] == str(plan)
    m = load_map(tmp_path / "sim_0004.yaml")
    ref = load_map(tmp_path / "sim_0004_reference.yaml")
    assert compute_brokenness(m, ref).degree == 2


def test_simulate_a_plan_with_no_room_for_the_robot_is_one_line(tmp_path, capsys):
    import numpy as np

    from brokenness import OCCUPIED, OccupancyMap, save_map

    states = np.full((40, 40), OCCUPIED, dtype=np.int8)
    save_map(OccupancyMap(states, 0.05, (0.0, 0.0, 0.0)), tmp_path / "solid.yaml")
    args = ["simulate", "--out", str(tmp_path / "out"), "--plan", str(tmp_path / "solid.yaml")]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no free cell of the plan is 0.4 m from every wall" in err


def test_simulate_a_plan_too_fine_for_the_cell_limit_is_one_line(tmp_path, capsys):
    """The grid follows the plan's extent (``--size`` is ignored): at 0.1 mm a cell the depot
    would need 312,000 x 163,500 cells, refused by the cell limit, naming the resolution."""
    plan = Path(__file__).parent / "data" / "depot.yaml"
    args = ["simulate", "--out", str(tmp_path), "--plan", str(plan), "--resolution", "0.0001"]
    assert main(args) == 2
    err = capsys.readouterr().err.splitlines()
    line = [e for e in err if "error" in e]
    assert len(line) == 1 and "a grid at 0.0001 m per cell" in line[0] and "--size" not in line[0]
