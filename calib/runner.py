"""Fan-out of independent seeded jobs (SBC datasets, many sensors) over dask.distributed.

``map_seeds(func, seeds)`` calls ``func(seed)`` for every seed and returns the results
in seed order. Each job builds its own ``numpy.random.default_rng(seed)``, so the result
does not depend on where or in which order it ran: the distributed run equals the serial
one exactly. ``scheduler``:

- ``None``: a ``LocalCluster`` of 2 worker processes (1 thread each) for the call;
- ``"serial"``: a plain loop in this process (no dask);
- ``"tcp://HOST:PORT"``: an existing ``dask-scheduler``.

``func`` must be picklable (a module-level function, or a ``functools.partial`` of one).
"""
from __future__ import annotations

from typing import Callable, Iterable, Sequence, TypeVar

from feeler.calib.progress import progress
from feeler.errors import ArgumentError

__all__ = ["map_seeds"]

R = TypeVar("R")


def map_seeds(func: Callable[[int], R], seeds: Iterable[int], *, scheduler: str | None = None,
              n_workers: int = 2, desc: str = "jobs", progress_bar: bool | None = None) -> list[R]:
    """``[func(s) for s in seeds]``, computed serially or on a dask cluster.

    Progress (:func:`feeler.calib.progress.progress`): a bar on a terminal, else a line
    per finished job with an estimate of the time left; none when ``progress_bar`` is False.

    Raises:
        ArgumentError: ``scheduler`` neither None, "serial" nor ``tcp://HOST:PORT``;
            ``n_workers`` < 1.
    """
    seeds = [int(s) for s in seeds]
    if n_workers < 1:
        raise ArgumentError("n_workers", n_workers, "must be >= 1")
    if scheduler == "serial":
        return [func(s) for s in progress(seeds, desc=desc, enabled=progress_bar, lines=True)]
    if scheduler is not None and not _is_tcp_address(scheduler):
        raise ArgumentError("scheduler", scheduler, "must be tcp://HOST:PORT (or omitted for a LocalCluster)")
    import logging

    from distributed import Client, LocalCluster, as_completed

    # dask logs every worker start/stop at INFO; show that only when feeler runs with -v
    dask_log = logging.getLogger("distributed")
    dask_log.setLevel(max(logging.getLogger().getEffectiveLevel(), logging.INFO))
    if scheduler is None:
        cluster = LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True,
                               dashboard_address=None, host="127.0.0.1")
        client = Client(cluster)
    else:
        cluster, client = None, Client(scheduler, timeout=10)
    try:
        futures = client.map(func, seeds, pure=False)
        for _ in progress(as_completed(futures), desc=desc, total=len(futures), enabled=progress_bar,
                          lines=True):
            pass
        return client.gather(futures)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def _is_tcp_address(text: str) -> bool:
    if not isinstance(text, str) or not text.startswith("tcp://"):
        return False
    host, _, port = text[len("tcp://"):].rpartition(":")
    return bool(host) and port.isdigit()


