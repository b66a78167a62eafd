"""The README and the documents under ``docs/`` point at what exists: their relative links
and the source, test and benchmark files they name (a newcomer follows them)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCUMENTS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]

#: ``[text](target)`` links that are not web addresses or anchors
_LINK = re.compile(r"\]\((?!https?://|#)([^)\s]+)\)")
#: a Python file named in backticks, with its folder or bare
_FILE = re.compile(r"`((?:[\w.]+/)*\w+\.py)`")


def _named_file(name: str) -> bool:
    """Whether a file named in the text exists: as a path from the repository's root, in
    ``src/`` or ``src/brokenness/`` (module paths), or a bare name in ``benchmarks/``,
    ``tests/`` or ``examples/``."""
    folders = ("", "src/", "src/brokenness/", "benchmarks/", "tests/", "examples/")
    return any((ROOT / folder / name).is_file() for folder in folders)


@pytest.mark.parametrize("document", DOCUMENTS, ids=lambda p: p.name)
def test_relative_links_point_at_files(document: Path) -> None:
    text = document.read_text(encoding="utf-8")
    missing = [t for t in _LINK.findall(text) if not (document.parent / t).exists()]
    assert not missing, f"{document.name} links to missing files: {missing}"


@pytest.mark.parametrize(
    "document", [d for d in DOCUMENTS if d.name != "benchmark-history.md"], ids=lambda p: p.name
)
def test_named_python_files_exist(document: Path) -> None:
    # the history records files of earlier sessions as they were; the README and the
    # account of the algorithm must name what is here now
    names = set(_FILE.findall(document.read_text(encoding="utf-8")))
    assert names, f"{document.name} names no Python file: the pattern is broken"
    missing = sorted(n for n in names if not _named_file(n))
    assert not missing, f"{document.name} names missing files: {missing}"


def test_readme_links_the_full_account_of_the_algorithm() -> None:
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert "](docs/algorithm.md)" in readme
    account = (ROOT / "docs" / "algorithm.md").read_text(encoding="utf-8")
    # the README's short steps and the full account use the same numbers
    for step in range(1, 12):
        assert re.search(rf"^{step}\. \*\*", readme, re.M), f"README step {step}"
        assert re.search(rf"^{step}\. \*\*", account, re.M), f"docs/algorithm.md step {step}"
