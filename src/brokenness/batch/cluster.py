"""A Dask client for a batch or a timeline: a running scheduler, or a cluster started here."""

from __future__ import annotations

import contextlib
import logging
from typing import Any

from .._optional import require
from ..errors import ParameterError

__all__ = ["check_scheduler", "dask_client", "import_distributed"]

#: Schemes of a Dask scheduler address ``SCHEME://HOST:PORT``; and ``inproc://``, a cluster
#: in this process (``LocalCluster(processes=False)``: ``inproc://HOST/PID/N``).
SCHEDULER_SCHEMES: tuple[str, ...] = ("tcp", "tls", "ws", "wss", "ucx")


def import_distributed() -> Any:
    """The ``distributed`` package, or a :class:`~brokenness.errors.MissingDependencyError`
    that says how to get it."""
    return require(
        "distributed", "running on a Dask cluster", "packages dask and distributed", "dask"
    )


def check_scheduler(address: str) -> None:
    """Refuse an address that is no Dask scheduler's (``[SCHEME://]HOST:PORT``) at once.

    ``distributed.Client`` would fail on it only after it has started its event loop, and
    the half-made client then waits 20 s at exit to close, with a traceback: the address is
    checked before any client is made (the scheme, a host and a port in 1..65535, or an
    ``inproc://`` address of a cluster in this process; whether a scheduler answers there is
    for the client to find out, within its connect timeout).

    Raises
    ------
    ParameterError
    """
    scheme, sep, location = str(address).rpartition("://")
    if not sep:
        scheme = "tcp"  # distributed's default scheme
    if scheme == "inproc":
        host, port = location, "1"
    elif location.startswith("["):  # an IPv6 address: [::1]:8786
        host, _, port = location[1:].partition("]")
        port = port[1:] if port.startswith(":") else ""
    else:
        host, _, port = location.rpartition(":")
    plain = bool(host) and host.isprintable() and not any(c.isspace() for c in host)
    number = port.isascii() and port.isdigit() and 0 < int(port) < 65536
    if not ((scheme in SCHEDULER_SCHEMES or scheme == "inproc") and plain and number):
        raise ParameterError(
            f"not a Dask scheduler address: {address!r} (expected [SCHEME://]HOST:PORT, e.g. "
            f"tcp://127.0.0.1:8786; schemes {', '.join(SCHEDULER_SCHEMES)})"
        )


def dask_client(
    scheduler: str | None, local_cluster: bool, workers: int, connect_timeout: float = 10.0
) -> tuple[Any, Any | None]:
    """A client of the scheduler at ``scheduler``, or of a ``LocalCluster`` of ``workers``
    one-thread processes started on this machine (``local_cluster``).

    Returns
    -------
    (client, cluster)
        ``cluster`` is the local cluster to close after the client, or ``None``.

    Raises
    ------
    ParameterError
        When the packages are missing, the address is not a scheduler's
        (:func:`check_scheduler`), the cluster cannot start or the scheduler cannot be
        reached (one line).
    """
    from .runner import one_line

    if not local_cluster:
        check_scheduler(scheduler or "")
    distributed = import_distributed()
    if local_cluster:
        try:
            cluster = distributed.LocalCluster(
                n_workers=workers,
                threads_per_worker=1,
                processes=True,
                host="127.0.0.1",
                dashboard_address=None,
                silence_logs=logging.ERROR,
            )
        except (OSError, RuntimeError, TimeoutError) as exc:
            raise ParameterError(f"cannot start a local Dask cluster: {one_line(exc)}") from None
        return distributed.Client(cluster, set_as_default=False), cluster
    try:
        client = distributed.Client(scheduler, timeout=connect_timeout, set_as_default=False)
    except Exception as exc:  # unreachable; TLS or UCX not set up here (TypeError...)
        _close_half_made(exc, distributed.Client)
        raise ParameterError(
            f"cannot connect to the Dask scheduler at {scheduler}: {one_line(exc)}"
        ) from None
    return client, None


def _close_half_made(exc: BaseException, client_type: type[Any]) -> None:
    """Close the client that a failed ``Client(...)`` left behind, at once.

    It is the ``self`` of a frame of ``exc``'s traceback (its ``__init__``). Left to the
    garbage collector, its ``__del__`` waits up to twice the connect timeout to close it and
    prints a traceback ("Exception ignored in: Client.__del__"); closed now it is gone in
    milliseconds, and its ``__del__`` then has nothing to do.
    """
    tb = exc.__traceback__
    while tb is not None:
        client = tb.tb_frame.f_locals.get("self")
        if isinstance(client, client_type):
            with contextlib.suppress(Exception):
                client.close(timeout=1)
            return
        tb = tb.tb_next
