"""The command line as researchers use it: pipes, verbosity, one-line warnings, help texts."""

from __future__ import annotations

import json
import subprocess
import sys
import types
import warnings
from pathlib import Path

import pytest

from brokenness.batch.manifest import read_manifest
from brokenness.batch.progress import _RateColumn
from brokenness.batch.runner import PairOptions, evaluate_pair
from brokenness.cli import main as cli_main
from brokenness.cli.main import EXIT_BROKEN_PIPE, build_parser, main

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "broken_building_31.yaml"
REFERENCE = ROOT / "examples" / "building_31.yaml"
DEPOT = ROOT / "tests" / "data" / "depot.yaml"

REQUIRED = {
    "compute": ["m.yaml", "r.yaml"],
    "register": ["r.yaml", "m.yaml"],
    "simulate": ["--out", "d"],
    "batch": ["m.csv", "--out", "d"],
    "compare": ["d"],
    "report": ["d", "--html", "o.html"],
    "timeline": ["b.bag", "r.yaml"],
}


@pytest.mark.parametrize("command", cli_main.SUBCOMMANDS)
def test_every_subcommand_has_quiet_and_verbose(command):
    parser = build_parser()
    args = parser.parse_args([command, *REQUIRED[command], "-q"])
    assert args.quiet and not args.verbose
    args = parser.parse_args([command, *REQUIRED[command], "--verbose"])
    assert args.verbose


@pytest.mark.parametrize("command", ["compute", "register", "batch", "compare", "simulate"])
def test_help_states_exit_codes_and_inputs(command, capsys):
    with pytest.raises(SystemExit):
        main([command, "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "exit status: 0" in text and "2 bad input" in text
    if command in ("compute", "register", "batch"):
        assert "ROS bags" in text
    if command == "compute":
        assert "3 not measured" in text and ".npy (OccupancyGrid values" in text
        assert "counter-clockwise" in text and "--label" in text


def test_register_has_topic_and_geometry():
    args = build_parser().parse_args(["register", "r.bag", "m.bag", "--topic", "/slam/map"])
    assert args.topic == "/slam/map" and args.moving_resolution is None


def test_broken_pipe_is_a_quiet_exit(monkeypatch, capsys):
    class Closed:
        def write(self, text):
            raise BrokenPipeError(32, "Broken pipe")

        def flush(self):
            raise BrokenPipeError(32, "Broken pipe")

        def isatty(self):
            return False

    monkeypatch.setattr(sys, "stdout", Closed())
    assert main(["compute", str(REFERENCE), str(REFERENCE), "--json", "-"]) == EXIT_BROKEN_PIPE
    assert capsys.readouterr().err == ""


def test_broken_pipe_from_a_real_pipe(tmp_path):
    code = (
        "import sys; from brokenness.cli.main import main; "
        f"sys.exit(main(['register', {str(REFERENCE)!r}, {str(EXAMPLE)!r}, '--candidates', '8']))"
    )
    shell = f'{sys.executable} -c "{code}" | head -c 10 > /dev/null; echo ${{PIPESTATUS[0]}}'
    done = subprocess.run(["bash", "-c", shell], capture_output=True, text=True, timeout=60)
    assert "Errno 32" not in done.stderr and "Traceback" not in done.stderr
    assert done.stdout.strip() in ("0", str(EXIT_BROKEN_PIPE))


def test_warnings_are_one_line(capsys):
    cli_main._show_warning(UserWarning("first line\n  second line"), UserWarning, "f.py", 1)
    err = capsys.readouterr().err
    assert err == "brokenness: warning: first line second line\n"


def test_register_returns_the_candidates_asked_for(capsys):
    assert main(["register", str(REFERENCE), str(EXAMPLE), "--candidates", "6", "--json", "-"]) == 0
    record = json.loads(capsys.readouterr().out)
    assert len(record["candidates"]) == 6 and "fewer_candidates" not in record
    # the best is the alignment of the largest part (59 % of the cells: rotation 0)
    assert abs(record["transform"]["rotation_deg"]) < 0.5
    assert main(["register", str(REFERENCE), str(EXAMPLE), "--candidates", "200"]) == 0
    out = capsys.readouterr().out
    assert "note: only" in out and "distinct hypotheses of the 200 asked for" in out
    assert "clockwise on screen" in out and "counter-clockwise" in out


def test_compute_summary_states_conventions_and_is_not_cut_when_piped():
    done = subprocess.run(
        [sys.executable, "-m", "brokenness.cli.main", "compute", str(EXAMPLE), str(REFERENCE)],
        capture_output=True,
        text=True,
        check=True,
        env={"COLUMNS": "30", "PATH": ""},
    )
    assert "…" not in done.stdout
    assert "+ = clockwise on screen" in done.stdout and "+ = counter-clockwise" in done.stdout
    assert "(3 partitions," in done.stdout
    # the evidence the degree rests on, with its limit
    assert "evidence: the map's free space crosses reference walls at " in done.stdout
    assert "(measured when at most 50 %)" in done.stdout
    assert (
        subprocess.run(
            [
                sys.executable,
                "-m",
                "brokenness.cli.main",
                "compute",
                str(EXAMPLE),
                str(REFERENCE),
                "-q",
            ],
            capture_output=True,
            text=True,
            check=True,
        ).stdout
        == ""
    )


def test_batch_rate_is_over_the_whole_run():
    task = types.SimpleNamespace(
        completed=4,
        elapsed=8.0,
        finished=False,
        finished_time=None,
        speed=932.0,
        finished_speed=None,
    )
    assert str(_RateColumn().render(task)) == "2.0 s/pair"
    task.completed, task.elapsed = 0, 0.5
    assert str(_RateColumn().render(task)) == "-- pairs/s"


def test_batch_worker_warnings_are_one_line_and_once(tmp_path):
    (tmp_path / "m.csv").write_text(f"map,reference\n{DEPOT},{DEPOT}\n")
    pair = read_manifest(tmp_path / "m.csv").pairs[0]
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # nothing escapes the worker
        row = evaluate_pair(pair, tmp_path, PairOptions(dpi=30))
    assert row.error is None
    assert len(row.warnings) == 1 and "205" in row.warnings[0]
    assert "\n" not in row.warnings[0]


def test_batch_warns_of_a_bare_image_and_of_a_mirrored_map(tmp_path):
    import numpy as np

    from brokenness import load_map

    ref = load_map(REFERENCE)
    nav = np.where(ref.states == 1, 100, np.where(ref.states == 0, 0, -1)).astype(np.int8)
    np.save(tmp_path / "image_order.npy", nav)  # OccupancyGrid values, rows top first
    (tmp_path / "m.csv").write_text(f"map,reference\n{tmp_path / 'image_order.npy'},{REFERENCE}\n")
    pair = read_manifest(tmp_path / "m.csv").pairs[0]
    row = evaluate_pair(pair, tmp_path, PairOptions(dpi=30))
    assert row.error is None
    text = " | ".join(row.warnings)
    assert "the map has none" in text and "far better mirrored" in text
