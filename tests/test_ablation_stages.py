"""``benchmarks/ablation.py`` switches stages of the measure off by replacing functions of the
package: each replacement must still fit the function it replaces (a stage's signature that
changed would make its ablation fail, or measure something else)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

import ablation  # noqa: E402

EXAMPLE = ROOT / "examples"


@pytest.mark.parametrize("stage", sorted(ablation.STAGES))
def test_the_bundled_example_is_measured_with_each_stage_switched_off(stage: str) -> None:
    code = "\n".join(
        [
            "import sys",
            f"sys.path.insert(0, {str(ROOT / 'benchmarks')!r})",
            "import ablation",
            f"ablation._switch_off({stage!r})",
            "from brokenness import compute_brokenness, load_map",
            f"m = load_map({str(EXAMPLE / 'broken_building_31.yaml')!r})",
            f"r = load_map({str(EXAMPLE / 'building_31.yaml')!r})",
            "print(compute_brokenness(m, r).degree)",
        ]
    )
    run = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=300, check=False
    )
    assert run.returncode == 0, run.stderr[-2000:]
    assert run.stdout.strip() == "2"
