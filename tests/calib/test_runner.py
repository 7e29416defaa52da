"""dask fan-out: identical results to the serial map for the same seeds."""
from __future__ import annotations

from functools import partial

import numpy as np
import pytest

from feeler.calib.runner import map_seeds
from feeler.errors import ArgumentError


def _seeded_job(seed: int, n: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(n, 3))
    return np.linalg.svd(x, compute_uv=False) + rng.standard_t(3)


def _job_and_sigint(seed: int, n: int):
    import signal
    return _seeded_job(seed, n), signal.getsignal(signal.SIGINT) == signal.SIG_IGN


def test_local_cluster_equals_serial():
    """... and its workers ignore SIGINT: a terminal's Ctrl-C reaches the whole process
    group, and each worker printed a KeyboardInterrupt traceback under 'feeler: interrupted'."""
    import signal

    job = partial(_seeded_job, n=50)
    seeds = range(100, 112)
    serial = map_seeds(job, seeds, scheduler="serial")
    # Python's own handler, as at a terminal: a suite run in the background of a script ignores
    # SIGINT already, and the workers would inherit that whatever the runner does
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        dist = map_seeds(partial(_job_and_sigint, n=50), seeds)     # LocalCluster, 2 processes on 127.0.0.1
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler    # ours again once they started
    finally:
        signal.signal(signal.SIGINT, previous)
    assert len(dist) == 12
    for a, (b, deaf) in zip(serial, dist):
        np.testing.assert_array_equal(a, b)
        assert deaf
    assert not np.array_equal(serial[0], serial[1])


def test_existing_scheduler_by_address():
    from distributed import LocalCluster
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                      dashboard_address=None, host="127.0.0.1", protocol="tcp") as cluster:
        addr = cluster.scheduler_address
        assert addr.startswith("tcp://")
        out = map_seeds(partial(_seeded_job, n=10), [3, 4], scheduler=addr)
    np.testing.assert_array_equal(out[1], _seeded_job(4, 10))


@pytest.mark.parametrize("kw, match", [
    ({"scheduler": "localhost:8786"}, "--scheduler='localhost:8786': tcp://HOST:PORT of a running dask scheduler, "
                                      "'serial' \\(in this process\\), or omitted"),
    ({"scheduler": "tcp://host:port"}, "tcp://HOST:PORT"),
    ({"n_workers": 0}, "n_workers=0: must be >= 1"),
])
def test_bad_arguments(kw, match):
    with pytest.raises(ArgumentError, match=match):
        map_seeds(abs, [1], **kw)


def test_an_address_without_a_scheduler_is_one_line(monkeypatch):
    """Nothing listens on the port: it was distributed's traceback ending in 'OSError: Timed
    out trying to connect to tcp://127.0.0.1:1 after 10 s'."""
    import socket

    import feeler.calib.runner as runner

    with socket.socket() as s:                       # a port that was free a moment ago
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    monkeypatch.setattr(runner, "CONNECT_TIMEOUT_S", 1.0)
    with pytest.raises(ArgumentError, match=rf"--scheduler='tcp://127.0.0.1:{port}': the address of a running dask "
                                            r"scheduler \(none answered within 1 s"):
        map_seeds(partial(_seeded_job, n=10), [1], scheduler=f"tcp://127.0.0.1:{port}")


def test_each_result_is_handed_over_as_it_finishes():
    """on_result(i, result) per job in this process, serially and on a cluster; the list
    returned is the same either way."""
    got = []
    assert map_seeds(abs, [-3, 4, -5], scheduler="serial", on_result=lambda i, r: got.append((i, r))) == [3, 4, 5]
    assert got == [(0, 3), (1, 4), (2, 5)]


def _dies_on_two(seed: int) -> int:
    import os
    if seed == 2:
        os._exit(3)                         # the worker process dies, as when the kernel kills it for memory
    return 10 * seed


def test_a_worker_that_dies_loses_only_the_jobs_it_held():
    """The jobs on the worker that died are the only ones lost: the others run on, each is
    handed over, and the error comes after them, saying how many were lost (it stopped at
    the first death, and a caller kept only what had finished by then). Which jobs the dead
    worker held besides the one that killed it (queued on it, with no retry) depends on the
    scheduler's timing: on a loaded machine it held two."""
    import re

    import dask
    import distributed  # noqa: F401  (its config first: set() below then restores it, not deletes it)

    from feeler.errors import FeelerError

    got = []
    # no retries: dask's default reruns the job on a fresh worker three times before giving up
    with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
        with pytest.raises(FeelerError, match=r"a dask worker died while computing jobs: \d of 5 lost "
                                              r"\(the first, job \d: .*the other \d finished") as info:
            map_seeds(_dies_on_two, range(5), on_result=lambda i, r: got.append((i, r)))
    lost, finished = (int(v) for v in re.search(r"(\d) of 5 lost.*the other (\d) finished", str(info.value)).groups())
    assert lost >= 1 and lost + finished == 5
    assert len(got) == finished and all(r == 10 * i for i, r in got) and 2 not in dict(got)


def test_a_ctrl_c_while_the_client_connects_stops_the_workers(monkeypatch):
    """The LocalCluster is up and the Ctrl-C lands in ``Client(cluster)``: the cluster's
    worker processes are stopped before the interrupt goes on, not left to the interpreter's exit."""
    import distributed
    import psutil

    made = []

    class Interrupted:
        def __init__(self, cluster, *a, **kw):
            made.append(cluster)
            raise KeyboardInterrupt

    monkeypatch.setattr(distributed, "Client", Interrupted)
    before = {p.pid for p in psutil.Process().children(recursive=True)}
    with pytest.raises(KeyboardInterrupt):
        map_seeds(partial(_seeded_job, n=5), range(4))
    assert len(made) == 1 and made[0].status.name == "closed"
    left = [p.cmdline() for p in psutil.Process().children(recursive=True) if p.pid not in before
            and p.is_running() and p.status() != psutil.STATUS_ZOMBIE]
    assert [c for c in left if not _lives_with_us(c)] == []


def _lives_with_us(cmdline: list[str]) -> bool:
    """multiprocessing's resource tracker and fork server (the workers' parent) stay until we exit."""
    text = " ".join(cmdline)
    return "multiprocessing.resource_tracker" in text or "multiprocessing.forkserver" in text


def test_a_ctrl_c_while_the_cluster_starts_is_not_lost(monkeypatch):
    """A Ctrl-C pressed while the LocalCluster starts is raised once it is up, and its
    workers are stopped: the workers were started with SIGINT ignored, process-wide, and
    a Ctrl-C in that second was lost (calibrate sensors then ran to the end, exit 0)."""
    import os
    import signal

    import distributed
    import psutil

    made = []
    real = distributed.LocalCluster

    def pressed_while_starting(*a, **kw):
        os.kill(os.getpid(), signal.SIGINT)             # as the terminal would, mid-start
        made.append(real(*a, **kw))
        return made[-1]

    monkeypatch.setattr(distributed, "LocalCluster", pressed_while_starting)
    before = {p.pid for p in psutil.Process().children(recursive=True)}
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)    # as at a terminal
    try:
        with pytest.raises(KeyboardInterrupt):
            map_seeds(partial(_seeded_job, n=5), range(4))
    finally:
        signal.signal(signal.SIGINT, previous)
    assert len(made) == 1 and made[0].status.name == "closed"
    left = [p.cmdline() for p in psutil.Process().children(recursive=True) if p.pid not in before
            and p.is_running() and p.status() != psutil.STATUS_ZOMBIE]
    assert [c for c in left if not _lives_with_us(c)] == []


def test_a_second_cluster_on_the_machine_prints_nothing():
    """The scheduler's HTTP server takes any free port: at its default 8787, held by another
    run, distributed warned "Port 8787 is already in use ... Hosting the HTTP server on port
    36369 instead", which reached the user of a second `calibrate sensors` as a warning line."""
    import socket
    import warnings

    with socket.socket() as held:
        held.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            held.bind(("127.0.0.1", 8787))
            held.listen()
        except OSError:
            pass                                      # another process holds it already: the same case
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            assert map_seeds(abs, [-1, 2]) == [1, 2]
    assert [str(w.message) for w in seen if "8787" in str(w.message)] == []
