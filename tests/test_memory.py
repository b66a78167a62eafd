"""How a computation's temporaries get their memory (:mod:`brokenness._memory`)."""

from __future__ import annotations

import resource

import numpy as np
import pytest

import brokenness._memory as memory
from brokenness._memory import MMAP_THRESHOLD_MAX, reused_pages

#: a grid's bytes over glibc's largest mmap threshold: without the block, a fresh mapping
LARGE = 4 * MMAP_THRESHOLD_MAX


class _Libc:
    """Records the ``mallopt`` and ``malloc_trim`` calls made of it."""

    def __init__(self) -> None:
        self.calls: list[tuple[str, int, int] | tuple[str, int]] = []

    def mallopt(self, param: int, value: int) -> int:
        self.calls.append(("mallopt", param, value))
        return 1

    def malloc_trim(self, pad: int) -> int:
        self.calls.append(("malloc_trim", pad))
        return 1


@pytest.fixture
def libc(monkeypatch: pytest.MonkeyPatch) -> _Libc:
    fake = _Libc()
    monkeypatch.setattr(memory, "_glibc", lambda: fake)
    for name in (*memory._TUNING, "GLIBC_TUNABLES"):
        monkeypatch.delenv(name, raising=False)
    return fake


def test_a_large_computation_keeps_freed_memory_and_gives_it_back_at_the_end(
    libc: _Libc,
) -> None:
    with pytest.raises(RuntimeError), reused_pages(LARGE):
        assert libc.calls == [("mallopt", -4, 0), ("mallopt", -1, 2**31 - 1)]
        raise RuntimeError("the defaults are set again however the block ends")
    defaults = [("mallopt", -4, 65536), ("mallopt", -1, 128 * 1024), ("malloc_trim", 0)]
    assert libc.calls[2:] == defaults


@pytest.mark.parametrize("tuning", ["MALLOC_MMAP_MAX_", "MALLOC_TRIM_THRESHOLD_", "GLIBC_TUNABLES"])
def test_malloc_is_left_alone_for_small_maps_and_where_the_user_tunes_it(
    libc: _Libc, monkeypatch: pytest.MonkeyPatch, tuning: str
) -> None:
    with reused_pages(MMAP_THRESHOLD_MAX):  # glibc reuses freed memory of this size itself
        pass
    value = "glibc.malloc.mmap_max=0" if tuning == "GLIBC_TUNABLES" else "0"
    monkeypatch.setenv(tuning, value)
    with reused_pages(LARGE):
        pass
    assert libc.calls == []


def _faults_of_two_grids() -> int:
    """Minor page faults of filling a large grid, freeing it and filling another."""
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    for _ in range(2):
        grid = np.empty(LARGE, np.uint8)
        grid.fill(1)
        del grid
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before


@pytest.mark.skipif(memory._glibc() is None, reason="glibc's malloc only")
def test_a_freed_grid_is_reused_without_page_faults(monkeypatch: pytest.MonkeyPatch) -> None:
    for name in (*memory._TUNING, "GLIBC_TUNABLES"):
        monkeypatch.delenv(name, raising=False)
    pages = LARGE // resource.getpagesize()
    # each grid a fresh mapping: every page of both faulted in (huge pages would fault less)
    with memory.small_pages():
        fresh = _faults_of_two_grids()
        with reused_pages(LARGE):
            reused = _faults_of_two_grids()
        after = _faults_of_two_grids()  # glibc's defaults again
    assert fresh > 1.5 * pages and after > 1.5 * pages
    assert reused < 1.25 * pages  # the second grid on the first one's pages
