"""brokenness report --html: a self-contained page, checked in a real headless browser."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

from brokenness.cli.main import main

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "broken_building_31.yaml"
REFERENCE = ROOT / "examples" / "building_31.yaml"


def _browser() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome", "chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


@pytest.fixture(scope="module")
def page(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("report")
    runs = out / "runs"
    runs.mkdir()
    for name, pair, labels in [
        ("broken", (EXAMPLE, REFERENCE), ["--label", "system=a"]),
        ("itself", (REFERENCE, REFERENCE), ["--label", "system=b"]),
    ]:
        args = ["compute", str(pair[0]), str(pair[1]), "-q", "--dpi", "40", *labels]
        assert main([*args, "--save-results", str(runs / f"{name}.zip")]) == 0
    (runs / "lost.error.json").write_text(
        '{"format": "brokenness-error", "labels": {"system": "c"}, "error": "no such file"}'
    )
    html = out / "report.html"
    assert main(["report", str(runs), "--html", str(html), "-q"]) == 0
    return html


def test_page_is_self_contained(page):
    text = page.read_text()
    assert text.startswith("<!DOCTYPE html>")
    assert not re.search(r"""(src|href)=["'](https?:|//)""", text)  # nothing from the network
    assert text.count("data:image/png;base64,") == 3  # two overlays and the compare figure
    assert "broken.zip" in text and "lost.error.json" in text and "no such file" in text
    assert "+ = clockwise on screen" in text


def _dom(page: Path, fragment: str = "") -> str:
    browser = _browser()
    if browser is None:
        pytest.skip("no chromium on this machine (apt-get install chromium)")
    done = subprocess.run(
        [
            browser,
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-dev-shm-usage",
            "--no-first-run",
            "--virtual-time-budget=5000",
            "--dump-dom",
            page.as_uri() + fragment,
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout


def _summary_order(dom: str) -> list[str]:
    body = dom.split('id="summary"', 1)[1].split("</table>", 1)[0]
    return re.findall(r'<td class="text" data-value="([^"]+)"', body)


def test_page_loads_offline_and_every_image_shows(page):
    dom = _dom(page)
    total = re.search(r'data-images-total="(\d+)"', dom)
    loaded = re.search(r'data-images-loaded="(\d+)"', dom)
    assert total and loaded and total.group(1) == loaded.group(1) == "3"


def test_table_sorts_in_the_browser(page):
    assert _summary_order(_dom(page)) == ["broken.zip", "itself.zip", "lost.error.json"]
    by_degree = _summary_order(_dom(page, "#sort=degree"))
    assert by_degree == ["itself.zip", "broken.zip", "lost.error.json"]  # empty last
    # a click sorts ascending, a second click descending (the header's own handler)
    desc = _dom(page, "#click=degree,degree")
    assert _summary_order(desc) == ["broken.zip", "itself.zip", "lost.error.json"]
    assert 'data-sorted="degree:desc"' in desc
    by_system = _summary_order(_dom(page, "#sort=label:system:desc"))
    assert by_system == ["lost.error.json", "itself.zip", "broken.zip"]
