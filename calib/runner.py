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
from feeler.errors import ArgumentError, FeelerError

__all__ = ["map_seeds", "shut_down", "SHUTDOWN_TIMEOUT_S"]

R = TypeVar("R")

CONNECT_TIMEOUT_S = 10.0     # s to reach an existing scheduler (--scheduler tcp://HOST:PORT)
SHUTDOWN_TIMEOUT_S = 30.0    # s a worker (or the client, the scheduler) gets to stop before it is killed


def map_seeds(func: Callable[[int], R], seeds: Iterable[int], *, scheduler: str | None = None,
              n_workers: int = 2, desc: str = "jobs", progress_bar: bool | None = None,
              on_result: Callable[[int, R], None] | None = None) -> list[R]:
    """``[func(s) for s in seeds]``, computed serially or on a dask cluster.

    ``on_result(i, result)`` is called in this process as each job finishes (the i-th seed;
    on a cluster in the order they finish), so that a caller can keep each result at once:
    a Ctrl-C then loses only the jobs not yet done, and a worker that dies only the jobs it
    held (running or queued on it, once dask's retries are spent): the others run on and are
    handed over before the error.

    Progress (:func:`feeler.calib.progress.progress`): a bar on a terminal, else a line
    per finished job with an estimate of the time left; none when ``progress_bar`` is False.

    The cluster is stopped in order (:func:`shut_down`); its log lines stay off stderr
    unless feeler runs with -v (:mod:`feeler.calib.dask_logging`).

    Raises:
        ArgumentError: ``scheduler`` neither None, "serial" nor ``tcp://HOST:PORT``, or no
            scheduler answering there; ``n_workers`` < 1.
        FeelerError: a worker process died (KilledWorker), after every other job finished.
    """
    seeds = [int(s) for s in seeds]
    if n_workers < 1:
        raise ArgumentError("n_workers", n_workers, "must be >= 1")
    if scheduler == "serial":
        out = []
        for i, s in enumerate(progress(seeds, desc=desc, enabled=progress_bar, lines=True)):
            out.append(func(s))
            if on_result is not None:
                on_result(i, out[-1])
        return out
    if scheduler is not None and not _is_tcp_address(scheduler):
        raise ArgumentError("--scheduler", scheduler, "tcp://HOST:PORT of a running dask scheduler, 'serial' "
                                                      "(in this process), or omitted for a LocalCluster here")
    from distributed import Client, KilledWorker, LocalCluster, as_completed

    from feeler.calib.dask_logging import cluster_options

    if scheduler is None:
        cluster = _local_cluster(LocalCluster, n_workers, cluster_options())
        try:
            client = Client(cluster)
        except BaseException:           # a Ctrl-C while the client connects: the workers are stopped, not orphaned
            cluster.close(timeout=SHUTDOWN_TIMEOUT_S)
            raise
    else:
        try:
            cluster, client = None, Client(scheduler, timeout=CONNECT_TIMEOUT_S)
        except OSError as exc:                  # distributed's TimeoutError is an OSError: no scheduler there
            raise ArgumentError("--scheduler", scheduler, f"the address of a running dask scheduler (none answered "
                                f"within {CONNECT_TIMEOUT_S:g} s: {exc.__class__.__name__}); start one with "
                                f"`dask scheduler` and workers with `dask worker {scheduler}`, or leave "
                                f"--scheduler out for workers on this machine") from None
    try:
        futures = client.map(func, seeds, pure=False)
        place = {f.key: i for i, f in enumerate(futures)}
        lost = []                              # jobs whose worker died (memory, a signal), past dask's retries
        for done in progress(as_completed(futures), desc=desc, total=len(futures), enabled=progress_bar,
                             lines=True):
            try:
                result = done.result()
            except KilledWorker as exc:        # the others go on: their results are still handed over
                lost.append((place[done.key], exc))
                continue
            if on_result is not None:
                on_result(place[done.key], result)
        if lost:
            first, exc = min(lost, key=lambda item: item[0])
            raise FeelerError(f"a dask worker died while computing {desc}: {len(lost)} of {len(futures)} lost "
                              f"(the first, job {first}: {exc}); the other {len(futures) - len(lost)} finished; "
                              f"run with -v to see the workers' log, or with --scheduler serial")
        return client.gather(futures)
    finally:
        shut_down(client, cluster)


def _local_cluster(local_cluster, n_workers: int, options: dict):
    """A ``LocalCluster`` whose worker processes never hear a terminal's Ctrl-C, without
    losing a Ctrl-C pressed while it starts.

    The workers are forked from multiprocessing's fork server (dask's
    ``multiprocessing-method`` set to ``forkserver`` for this process), which is started
    with SIGINT ignored (:func:`feeler.children.sigint_ignored`, 0.2 s, once a process):
    forked from it, every worker inherits that. The cluster itself then starts with
    SIGINT only recorded, and a Ctrl-C pressed meanwhile stops it and is raised once it
    is up. Spawned from here instead (dask's default), the workers had to be started
    inside the ignoring block, and a Ctrl-C in its 0.8-1.5 s was lost: ``calibrate
    sensors`` of three datasets interrupted 1.5 s in ran to the end, exit 0."""
    import multiprocessing.forkserver

    import dask
    from distributed.utils import get_mp_context

    from feeler.children import sigint_handler, sigint_ignored

    dask.config.set({"distributed.worker.multiprocessing-method": "forkserver"})   # also for a restarted worker
    get_mp_context()                    # sets the fork server's imports (distributed's own choice)
    with sigint_ignored():
        multiprocessing.forkserver.ensure_running()
    pressed = []
    with sigint_handler(lambda *_: pressed.append(True)):
        # no dashboard; the scheduler's HTTP server (health, metrics) on any free port: at
        # its default 8787 a second run on the machine printed "Port 8787 is already in use"
        cluster = local_cluster(n_workers=n_workers, threads_per_worker=1, processes=True,
                                dashboard_address=None, scheduler_kwargs={"dashboard_address": ":0"},
                                host="127.0.0.1", **options)
    if pressed:
        cluster.close(timeout=SHUTDOWN_TIMEOUT_S)
        raise KeyboardInterrupt
    return cluster


def shut_down(client, cluster, timeout_s: float = SHUTDOWN_TIMEOUT_S) -> None:
    """Stop a map's dask objects in order: the client (no more requests), then each
    worker while the scheduler still runs (so none loses it mid-heartbeat), each given
    ``timeout_s`` to exit before its nanny kills it, then the cluster (scheduler).

    ``cluster`` None: only the client (an existing scheduler is not ours to stop).
    distributed's own ``cluster.close()`` gives each worker 4 s, which a loaded machine
    overruns ("Worker process still alive after 4.0 seconds, killing")."""
    try:
        client.close(timeout=timeout_s)
    finally:
        if cluster is not None:
            try:
                cluster.sync(_close_workers, list(cluster.workers.values()), timeout_s)
            finally:
                cluster.close(timeout=timeout_s)


async def _close_workers(workers, timeout_s: float) -> None:
    import asyncio

    await asyncio.gather(*(w.close(timeout=timeout_s) for w in workers))


def _is_tcp_address(text: str) -> bool:
    if not isinstance(text, str) or not text.startswith("tcp://"):
        return False
    host, _, port = text[len("tcp://"):].rpartition(":")
    return bool(host) and port.isdigit()


