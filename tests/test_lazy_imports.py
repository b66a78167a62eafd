"""What each process loads: the batch process only reads, its workers start warm.

``import brokenness`` and the command line load neither numpy, SciPy, OpenCV, Pillow nor
matplotlib (the public names are imported on first use: :mod:`brokenness._lazy`); a
``brokenness batch --workers 2`` process never loads them either, while its fork server
preloads every module a worker needs, so that no worker imports any on its first pair.
Each check runs in a fresh interpreter (``sys.modules`` of this one holds everything).
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

import brokenness

ROOT = Path(__file__).resolve().parents[1]
DEPOT = ROOT / "tests" / "data" / "depot.yaml"
HEAVY = ("numpy", "scipy", "cv2", "PIL", "yaml", "matplotlib", "rich", "dask", "rosbags")


def _loaded(code: str) -> dict:
    """Run ``code`` in a fresh interpreter; it prints a JSON object last."""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


_HEAVY_LOADED = (
    "import json, sys; print(json.dumps(sorted({m.split('.')[0] for m in sys.modules} "
    f"& set({HEAVY!r}))))"
)


def test_import_brokenness_loads_no_heavy_library():
    assert _loaded("import brokenness\n" + _HEAVY_LOADED) == []


def test_the_command_line_parser_loads_no_heavy_library():
    code = "from brokenness.cli.main import build_parser\nbuild_parser()\n" + _HEAVY_LOADED
    assert _loaded(code) == []


def test_batch_modules_load_no_heavy_library():
    code = "import brokenness.batch, brokenness.batch.runner, brokenness.io\n" + _HEAVY_LOADED
    assert _loaded(code) == []


def test_every_public_name_is_the_one_of_its_module():
    from brokenness import grid, io, measure, registration, simulation, transform
    from brokenness.timeline import run

    for name in brokenness.__all__:
        assert hasattr(brokenness, name), name
    assert set(brokenness.__all__) <= set(dir(brokenness))
    assert brokenness.compute_brokenness is measure.recursion.compute_brokenness
    assert brokenness.OccupancyMap is grid.OccupancyMap
    assert brokenness.load_map is io.load.load_map
    assert brokenness.register is registration.api.register
    assert brokenness.simulate_broken_map is simulation.synthetic.simulate_broken_map
    assert brokenness.RigidTransform is transform.RigidTransform
    assert brokenness.timeline is run.timeline
    for package in (io, measure, registration):
        for name in package.__all__:
            assert hasattr(package, name), f"{package.__name__}.{name}"
    with pytest.raises(AttributeError, match="no attribute 'nonsense'"):
        _ = brokenness.nonsense


def test_timeline_stays_the_function_when_its_subpackage_is_imported_first():
    code = (
        "import json, brokenness\n"
        "from brokenness.timeline import TimelineResult\n"
        "import brokenness.timeline.output\n"
        "print(json.dumps([callable(brokenness.timeline), type(brokenness.timeline).__name__, "
        "'numpy' in __import__('sys').modules]))"
    )
    assert _loaded(code) == [True, "function", True]


def test_a_star_import_gives_every_public_name():
    namespace: dict = {}
    exec("from brokenness import *", namespace)  # noqa: S102 - the names of __all__
    assert set(brokenness.__all__) <= set(namespace)
    assert namespace["timeline"] is brokenness.timeline


def test_the_batch_process_with_workers_loads_no_heavy_library(tmp_path):
    (tmp_path / "m.csv").write_text(f"map,reference,copy\n{DEPOT},{DEPOT},1\n{DEPOT},{DEPOT},2\n")
    argv = ["batch", str(tmp_path / "m.csv"), "--out", str(tmp_path / "o"), "--workers", "2"]
    code = (
        "import json, sys\nfrom brokenness.cli.main import main\n"
        f"code = main({argv + ['--no-progress', '-q']!r})\n"
        "heavy = sorted({m.split('.')[0] for m in sys.modules} & "
        "{'numpy', 'scipy', 'cv2', 'PIL', 'yaml', 'matplotlib'})\n"
        "print(json.dumps([code, heavy]))"
    )
    assert _loaded(code) == [0, []]
    assert len(list((tmp_path / "o").glob("*.zip"))) == 2


@pytest.mark.parametrize("overlays", ["fast", "figure", "none"])
def test_the_fork_server_preloads_what_a_worker_imports(tmp_path, overlays):
    """After the preload, evaluating a pair imports nothing of the pipeline or its
    libraries: a worker forked from the fork server starts its first pair warm."""
    (tmp_path / "m.csv").write_text(f"map,reference\n{DEPOT},{DEPOT}\n")
    code = (
        "import importlib, json, sys, warnings\n"
        "from brokenness.batch.runner import PairOptions, _preload, evaluate_pair\n"
        "from brokenness.batch import read_manifest\n"
        f"options = PairOptions(overlays={overlays!r})\n"
        "for name in _preload(options):\n"
        "    importlib.import_module(name)\n"
        f"pair = read_manifest({str(tmp_path / 'm.csv')!r}).pairs[0]\n"
        "before = set(sys.modules)\n"
        f"row = evaluate_pair(pair, {str(tmp_path)!r}, options)\n"
        "new = sorted(m for m in set(sys.modules) - before if m.split('.')[0] in "
        f"{(*HEAVY, 'brokenness')!r})\n"
        "print(json.dumps([row.error, new]))"
    )
    assert _loaded(code) == [None, []]


def test_the_batch_overlay_kinds_are_those_of_the_result_files():
    from brokenness.batch.manifest import OVERLAY_KINDS
    from brokenness.report.results import OVERLAY_KINDS as SAVED

    assert OVERLAY_KINDS == SAVED
