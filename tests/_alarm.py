"""A guard for tests of inputs that could hang (FIFOs, devices): fail instead of waiting."""

from __future__ import annotations

import contextlib
import signal
from collections.abc import Iterator


@contextlib.contextmanager
def alarm(seconds: int = 20) -> Iterator[None]:
    """Fail (instead of hanging) when the block takes longer than ``seconds``."""

    def hung(signum: int, frame: object) -> None:
        raise TimeoutError(f"hung for more than {seconds} s")

    previous = signal.signal(signal.SIGALRM, hung)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
