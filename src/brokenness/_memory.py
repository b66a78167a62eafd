"""How the large temporaries of one computation get their memory.

numpy asks the kernel for transparent huge pages (``madvise(MADV_HUGEPAGE)``) for every array
of 4 MiB or more. Where the kernel then compacts memory synchronously to find a free huge
page (``/sys/kernel/mm/transparent_hugepage/defrag`` set to ``madvise``, the usual default)
and memory is fragmented, the first touch of each fresh array costs far more than it saves:
on the 2-core machine of the benchmarks, a fresh 190 MiB float32 grid took 1.9-2.7 s to fill
with huge pages against 0.2-0.4 s without, and the system time of an 8000 x 8000 map was
larger than its user time. :func:`small_pages` turns the advice off for the duration of one
computation and restores it after (results do not depend on it; only the time does).

glibc's ``malloc`` serves every allocation of more than 32 MiB (its largest threshold on 64-bit
systems) from a fresh mapping and gives it back to the kernel when it is freed: each whole-grid
temporary of a large map then costs a page fault, and a page of zeros from the kernel, for
every 4 KiB it touches. On the 10000 x 10000 map of degree 8 of ``benchmarks/bench_scale.py``
that was 1.4 million page faults and 5.1 s of system time in a call of 13-25 s.
:func:`reused_pages` makes the heap serve them for the duration of one computation of a map
that large, so that a freed grid's pages go to the next one, and gives the free memory back
to the kernel at the end (results do not depend on it; only the time and the peak do).
"""

from __future__ import annotations

import ctypes
import os
import platform
import sys
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["reused_pages", "small_pages"]

#: glibc's largest threshold for serving an allocation from a fresh mapping, on 64-bit
#: systems (``DEFAULT_MMAP_THRESHOLD_MAX``): smaller arrays come from the heap already, once
#: one of their size has been freed (the threshold follows the largest freed)
MMAP_THRESHOLD_MAX = 32 * 2**20
#: ``mallopt`` parameters (``malloc.h``) and glibc's defaults of the two set here
_M_TRIM_THRESHOLD, _M_MMAP_MAX = -1, -4
_DEFAULT_TRIM_THRESHOLD, _DEFAULT_MMAP_MAX = 128 * 1024, 65536
#: free memory at the top of the heap kept by the process within the block (``int``: 2 GiB)
_KEEP = 2**31 - 1
#: the environment through which a user tunes glibc's malloc: then it is left as it is
_TUNING = (
    "MALLOC_MMAP_MAX_",
    "MALLOC_MMAP_THRESHOLD_",
    "MALLOC_TRIM_THRESHOLD_",
    "MALLOC_TOP_PAD_",
)


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


@contextmanager
def reused_pages(largest: int) -> Iterator[None]:
    """Within the block, glibc's ``malloc`` keeps freed memory and serves large arrays from it.

    Applied where the largest array of the computation, ``largest`` bytes (a ``float32`` grid
    of the larger map), is over :data:`MMAP_THRESHOLD_MAX`: below it glibc reuses freed
    memory already. Inside the block no allocation gets a fresh mapping (``M_MMAP_MAX`` 0)
    and freed memory stays with the process (``M_TRIM_THRESHOLD`` 2 GiB); on leaving it,
    glibc's defaults of the two are set again and the free memory is given back to the kernel
    (``malloc_trim``). Nothing is done where the C library is not glibc, or where the user
    tunes its ``malloc`` through the environment (``MALLOC_*_`` variables or
    ``GLIBC_TUNABLES``). The setting is the process's: another thread allocating meanwhile is
    served in the same way, which changes its speed and memory, never its results.
    """
    libc = None if largest <= MMAP_THRESHOLD_MAX or _user_tuned() else _glibc()
    if libc is None:
        yield
        return
    libc.mallopt(_M_MMAP_MAX, 0)
    libc.mallopt(_M_TRIM_THRESHOLD, _KEEP)
    try:
        yield
    finally:
        libc.mallopt(_M_MMAP_MAX, _DEFAULT_MMAP_MAX)
        libc.mallopt(_M_TRIM_THRESHOLD, _DEFAULT_TRIM_THRESHOLD)
        libc.malloc_trim(0)


def _user_tuned() -> bool:
    """Whether the environment tunes glibc's ``malloc``."""
    return any(name in os.environ for name in _TUNING) or "glibc.malloc" in os.environ.get(
        "GLIBC_TUNABLES", ""
    )


def _glibc() -> ctypes.CDLL | None:
    """The running glibc, with ``mallopt`` and ``malloc_trim`` typed; None elsewhere."""
    if not sys.platform.startswith("linux") or platform.libc_ver()[0] != "glibc":
        return None
    try:
        libc = ctypes.CDLL(None)
        mallopt, trim = libc.mallopt, libc.malloc_trim
    except (OSError, AttributeError):
        return None
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    trim.argtypes, trim.restype = [ctypes.c_size_t], ctypes.c_int
    return libc
