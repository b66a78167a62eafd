"""How the large temporaries of one computation get their memory.

numpy asks the kernel for transparent huge pages (``madvise(MADV_HUGEPAGE)``) for every array
of 4 MiB or more. Where the kernel then compacts memory synchronously to find a free huge
page (``/sys/kernel/mm/transparent_hugepage/defrag`` set to ``madvise``, the usual default)
and memory is fragmented, the first touch of each fresh array costs far more than it saves:
on the 2-core machine of the benchmarks, a fresh 190 MiB float32 grid took 1.9-2.7 s to fill
with huge pages against 0.2-0.4 s without, and the system time of an 8000 x 8000 map was
larger than its user time. :func:`small_pages` turns the advice off for the duration of one
computation and restores it after (results do not depend on it; only the time does).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["small_pages"]


@contextmanager
def small_pages() -> Iterator[None]:
    """Within the block, numpy does not ask for huge pages for new arrays.

    The setting is numpy's, for the whole process; it is restored on leaving the block (a
    numpy without it leaves everything as it is). Another thread allocating meanwhile gets
    ordinary pages too, which changes its speed, never its results. numpy is imported here,
    not with this module.
    """
    try:  # numpy >= 2
        from numpy._core import multiarray
    except ImportError:  # pragma: no cover - numpy 1.26
        from numpy.core import multiarray  # type: ignore[no-redef]

    setter = getattr(multiarray, "_set_madvise_hugepage", None)
    if setter is None:
        yield
        return
    previous = bool(setter(False))
    try:
        yield
    finally:
        setter(previous)
