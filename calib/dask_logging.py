"""dask.distributed's log lines reach stderr only with ``feeler -v`` (issue 16 item 5).

dask.distributed logs from two kinds of process. This one holds the client, the
scheduler and the nannies that start, watch and stop the workers (a nanny's "Worker
process still alive after 4.0 seconds, killing" when a loaded machine stops a worker
late). Each worker is a process of its own, spawned afresh: it configures its logging
from the dask config it finds in its environment and writes to the stderr it inherits
(a worker's "Failed to communicate with scheduler during heartbeat" and its traceback,
when the scheduler went first). :func:`quiet` covers both:

- here, a :class:`QuietFilter` on the root logger's handlers drops every record of the
  ``distributed``, ``tornado`` and ``bokeh`` trees, whatever level someone sets later;
- in the workers, ``DASK_LOGGING`` (read by dask in every process that inherits the
  environment) puts every logger distributed configures at :data:`SILENT`, and
  :func:`cluster_options` does the same for the nanny's logger inside a worker.

With ``-v`` nothing is changed: distributed logs as it is configured to (INFO: every
worker start and stop).
"""
from __future__ import annotations

import logging
import os

__all__ = ["TREES", "SILENT", "DASK_ENV", "QuietFilter", "in_trees", "quiet", "is_quiet", "cluster_options"]

TREES = ("distributed", "tornado", "bokeh")      # the loggers (with their children) distributed configures
SILENT = logging.CRITICAL + 10                   # above the level of any record
DASK_ENV = "DASK_LOGGING"
# every logger distributed.config gives a level of its own, and the nanny's (a worker's _run sets it)
_LEVELS = {name: SILENT for name in ("distributed", "distributed.client", "distributed.gc", "distributed.nanny",
                                     "distributed.worker", "tornado", "tornado.application", "bokeh")}


def in_trees(name: str) -> bool:
    """Whether the logger ``name`` is one of :data:`TREES` or below one."""
    return any(name == tree or name.startswith(tree + ".") for tree in TREES)


class QuietFilter(logging.Filter):
    """Drops the records of :data:`TREES` (a handler filter: it sees every record that
    reaches the handler, from any logger below, whatever that logger's level)."""

    def filter(self, record: logging.LogRecord) -> bool:
        return not in_trees(record.name)


def quiet(verbose: int) -> None:
    """With ``verbose`` 0: no log line of dask.distributed on stderr, from this process or
    from any worker process it starts later; otherwise nothing changes.

    Installs :class:`QuietFilter` on the root logger's handlers (call it after
    ``logging.basicConfig``), sets the :data:`TREES` loggers here to :data:`SILENT`,
    and ``DASK_LOGGING`` in the environment unless the user set it."""
    if verbose:
        return
    os.environ.setdefault(DASK_ENV, repr(_LEVELS))
    for handler in logging.getLogger().handlers:
        if not any(isinstance(f, QuietFilter) for f in handler.filters):
            handler.addFilter(QuietFilter())
    for name in _LEVELS:
        logging.getLogger(name).setLevel(SILENT)


def is_quiet() -> bool:
    """Whether :func:`quiet` silenced dask.distributed in this process."""
    return any(isinstance(f, QuietFilter) for h in logging.getLogger().handlers for f in h.filters)


def cluster_options() -> dict:
    """Keywords for ``LocalCluster``: when quiet, ``silence_logs`` at :data:`SILENT` (the
    level a worker process gives its nanny logger); otherwise none (distributed's own)."""
    return {"silence_logs": SILENT} if is_quiet() else {}
