"""A Dask client for a batch or a timeline: a running scheduler, or a cluster started here."""

from __future__ import annotations

import logging
from typing import Any

from .._optional import require
from ..errors import ParameterError

__all__ = ["dask_client", "import_distributed"]


def import_distributed() -> Any:
    """The ``distributed`` package, or a :class:`~brokenness.errors.MissingDependencyError`
    that says how to get it."""
    return require(
        "distributed", "running on a Dask cluster", "packages dask and distributed", "dask"
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
        When the packages are missing, the cluster cannot start or the scheduler cannot be
        reached (one line).
    """
    from .runner import one_line

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
    except (OSError, TimeoutError, ValueError) as exc:
        raise ParameterError(
            f"cannot connect to the Dask scheduler at {scheduler}: {one_line(exc)}"
        ) from None
    return client, None
