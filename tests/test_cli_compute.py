"""The ``brokenness compute`` command: output, files, exit codes, one-line errors."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from brokenness.cli.main import main

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "broken_building_31.yaml"
REFERENCE = ROOT / "examples" / "building_31.yaml"


def test_bundled_example_gives_its_expected_degree(capsys):
    assert main(["compute", str(EXAMPLE), str(REFERENCE), "--json", "-"]) == 0
    record = json.loads(capsys.readouterr().out)
    truth = json.loads((ROOT / "examples" / "broken_building_31_truth.json").read_text())
    assert record["degree"] == truth["expected_degree"] == 2
    found = sorted(p["transform"]["rotation_deg"] for p in record["partitions"])
    expected = sorted(p["rotation_deg"] for p in truth["partitions"])
    np.testing.assert_allclose(found, expected, atol=0.5)
    for p in record["partitions"]:
        assert set(p) >= {"cells", "fraction", "transform", "confidence", "displacement_m"}
        assert "translation_m" in p["transform"]["world"]


def test_summary_json_file_and_overlay(tmp_path, capsys):
    out_json = tmp_path / "r.json"
    overlay = tmp_path / "o.png"
    args = ["compute", str(EXAMPLE), str(REFERENCE), "--json", str(out_json)]
    code = main([*args, "--overlay", str(overlay)])
    assert code == 0
    text = capsys.readouterr().out
    assert "degree of brokenness: 2" in text
    assert "unassigned:" in text
    assert json.loads(out_json.read_text())["degree"] == 2
    assert overlay.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def _write(name: str, data: bytes):
    def make(folder: Path) -> Path:
        path = folder / name
        path.write_bytes(data)
        return path

    return make


@pytest.mark.parametrize(
    "setup, message",
    [
        (lambda d: d / "missing.yaml", "no such file"),
        (_write("bad.pgm", b"P5\n10 10\n255\n" + b"\0" * 7), "truncated"),
        (_write("list.yaml", b"- 1\n- 2\n"), "list.yaml"),
        (_write("empty.npy", b""), "empty.npy"),
        (_write("noimage.yaml", b"image: nothere.pgm\nresolution: 0.05\n"), "nothere.pgm"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, setup, message):
    path = setup(tmp_path)
    assert main(["compute", str(path), str(REFERENCE)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert message.lower() in err.lower()


def test_map_without_occupied_cells(tmp_path, capsys):
    np.save(tmp_path / "free.npy", np.zeros((30, 30), bool))
    assert main(["compute", str(tmp_path / "free.npy"), str(REFERENCE)]) == 2
    assert "no occupied cell" in capsys.readouterr().err


def test_bad_option_exits_2(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["compute", str(EXAMPLE), str(REFERENCE), "--method", "magic"])
    assert exc.value.code == 2
    assert main(["compute", str(EXAMPLE), str(REFERENCE), "--threshold", "-1"]) == 2
    assert "threshold" in capsys.readouterr().err


def test_console_script_runs(tmp_path):
    exe = shutil.which("brokenness", path=str(Path(sys.executable).parent))
    if exe is None:
        pytest.skip("console script not installed in this environment")
    done = subprocess.run(
        [exe, "compute", str(REFERENCE), str(REFERENCE), "--json", "-"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["degree"] == 0


def test_warnings_are_one_line(capsys):
    depot = ROOT / "tests" / "data" / "depot.yaml"
    assert main(["compute", str(depot), str(depot)]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert err and all(line.startswith("brokenness: warning: ") for line in err)
    assert any("free_thresh" in line for line in err)
