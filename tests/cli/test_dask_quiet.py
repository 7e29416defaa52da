"""dask.distributed stays off stderr unless -v: the quiet filter here (the nanny's "Worker
process still alive after 4.0 seconds, killing"), the config its worker processes inherit
(a worker's "Failed to communicate with scheduler during heartbeat"), and a cluster
stopped in order (client, workers with time to exit, then the scheduler)."""
from __future__ import annotations

import asyncio
import logging
import subprocess
import sys

import pytest

from feeler.calib.dask_logging import DASK_ENV, QuietFilter, in_trees
from feeler.calib.runner import SHUTDOWN_TIMEOUT_S, shut_down
from tests.cli._run import ENV, ROOT

NANNY = "Worker process still alive after 4.0 seconds, killing"

# what feeler.cli.main does before a command: basicConfig, then the quiet set-up
HERE = ("import logging, sys\n"
        "logging.basicConfig(level=[logging.WARNING, logging.INFO][{v}], format='%(levelname)s %(name)s: %(message)s')\n"
        "from feeler.cli import _quiet_third_parties\n"
        "_quiet_third_parties({v})\n"
        "nanny = logging.getLogger('distributed.nanny')\n"
        f"nanny.warning({NANNY!r})\n"
        "nanny.setLevel(logging.DEBUG)                     # whoever lowers the level later\n"
        "logging.getLogger('distributed').setLevel(logging.INFO)\n"
        "nanny.error('nanny error')\n"
        "logging.getLogger('distributed.core').warning('Event loop was unresponsive in Nanny for 4.1s')\n"
        "logging.getLogger('tornado.application').error('Exception in callback')\n"
        "logging.getLogger('feeler.hardware').warning('ours')\n")


def _env_without_dask_logging() -> dict:
    return {k: v for k, v in ENV.items() if k != DASK_ENV}


def test_the_quiet_filter_covers_the_nanny_logger():
    out = subprocess.run([sys.executable, "-c", HERE.format(v=0)], cwd=ROOT, env=_env_without_dask_logging(),
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stderr == "WARNING feeler.hardware: ours\n"


def test_with_v_every_line_shows():
    out = subprocess.run([sys.executable, "-c", HERE.format(v=1)], cwd=ROOT, env=_env_without_dask_logging(),
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert f"WARNING distributed.nanny: {NANNY}" in out.stderr and "ERROR distributed.nanny: nanny error" \
        in out.stderr and "Event loop was unresponsive" in out.stderr and "WARNING feeler.hardware: ours" in out.stderr


def test_the_filter_knows_the_trees():
    assert all(in_trees(n) for n in ("distributed", "distributed.nanny", "distributed.worker.memory", "tornado",
                                     "tornado.application", "bokeh.server"))
    assert not any(in_trees(n) for n in ("distributedx", "feeler", "feeler.distributed", "pymc", "root"))
    record = logging.LogRecord("distributed.nanny", logging.CRITICAL, __file__, 1, NANNY, None, None)
    assert QuietFilter().filter(record) is False


WORKER = ("import logging, distributed\n"            # a fresh process, as a spawned worker: dask config from env
          "logging.getLogger('distributed.worker').error('Failed to communicate with scheduler during heartbeat.')\n"
          "logging.getLogger('distributed.nanny').critical('nanny in the worker')\n"
          "logging.getLogger('tornado.application').error('Exception in callback')\n"
          "print('ran')\n")


def test_worker_processes_inherit_the_silence():
    """A worker configures its own logging from the environment: set up as feeler -v does
    not, the same lines print (the control: the check can fail)."""
    spawn = ("import logging, os, subprocess, sys\n"
             "logging.basicConfig()\n"
             "from feeler.cli import _quiet_third_parties\n"
             "_quiet_third_parties(int(sys.argv[1]))\n"
             f"r = subprocess.run([sys.executable, '-c', {WORKER!r}], capture_output=True, text=True)\n"
             "sys.stdout.write(r.stdout); sys.stderr.write(r.stderr)\n")
    quiet = subprocess.run([sys.executable, "-c", spawn, "0"], cwd=ROOT, env=_env_without_dask_logging(),
                           capture_output=True, text=True, timeout=120)
    assert quiet.stdout == "ran\n" and quiet.stderr == ""
    loud = subprocess.run([sys.executable, "-c", spawn, "1"], cwd=ROOT, env=_env_without_dask_logging(),
                          capture_output=True, text=True, timeout=120)
    assert loud.stdout == "ran\n" and "Failed to communicate with scheduler during heartbeat" in loud.stderr


def test_a_users_own_dask_logging_is_kept():
    code = ("import os, logging\nlogging.basicConfig()\nfrom feeler.calib.dask_logging import quiet\n"
            f"quiet(0)\nprint(os.environ[{DASK_ENV!r}])\n")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env={**ENV, DASK_ENV: "{'distributed': 'info'}"},
                         capture_output=True, text=True, timeout=60)
    assert out.stdout == "{'distributed': 'info'}\n"


class _Recorder:
    def __init__(self):
        self.calls = []


class _Client:
    def __init__(self, rec):
        self.rec = rec

    def close(self, timeout=None):
        self.rec.calls.append(("client.close", timeout))


class _Worker:
    def __init__(self, rec, name):
        self.rec, self.name = rec, name

    async def close(self, timeout=None):
        self.rec.calls.append((f"{self.name}.close", timeout))


class _Cluster:
    def __init__(self, rec):
        self.rec = rec
        self.workers = {0: _Worker(rec, "worker0"), 1: _Worker(rec, "worker1")}

    def sync(self, func, *args):
        return asyncio.run(func(*args))

    def close(self, timeout=None):
        self.rec.calls.append(("cluster.close", timeout))


def test_shut_down_in_order_with_time_for_a_loaded_machine():
    rec = _Recorder()
    shut_down(_Client(rec), _Cluster(rec))
    assert rec.calls[0] == ("client.close", SHUTDOWN_TIMEOUT_S)
    assert sorted(rec.calls[1:3]) == [("worker0.close", SHUTDOWN_TIMEOUT_S), ("worker1.close", SHUTDOWN_TIMEOUT_S)]
    assert rec.calls[3:] == [("cluster.close", SHUTDOWN_TIMEOUT_S)]
    assert SHUTDOWN_TIMEOUT_S * 0.8 >= 20          # a nanny kills after 0.8 x its timeout; distributed's own: 4 s


def test_shut_down_of_an_existing_scheduler_closes_only_the_client():
    rec = _Recorder()
    shut_down(_Client(rec), None, timeout_s=7.0)
    assert rec.calls == [("client.close", 7.0)]


def test_the_cluster_closes_even_when_a_worker_will_not():
    rec = _Recorder()
    cluster = _Cluster(rec)

    async def stuck(timeout=None):
        raise asyncio.TimeoutError
    cluster.workers[0].close = stuck
    with pytest.raises(asyncio.TimeoutError):
        shut_down(_Client(rec), cluster)
    assert rec.calls[-1] == ("cluster.close", SHUTDOWN_TIMEOUT_S)


def _die(seed: int) -> int:
    import os
    os._exit(3)


def test_a_worker_that_dies_is_a_one_line_failure():
    import dask
    import distributed  # noqa: F401  (its config first: set() below then restores it, not deletes it)

    from feeler.calib.runner import map_seeds
    from feeler.errors import FeelerError

    with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
        with pytest.raises(FeelerError, match=r"^a dask worker died while computing deaths: 1 of 1 lost \(the first, job 0: .*\); "
                                              r"the other 0 finished; run with -v"):
            map_seeds(_die, [1], n_workers=1, desc="deaths")
