"""Real-time scheduling for the acquisition loop, where the system permits it.

On a shared machine the kernel's fair scheduler (EEVDF) lets a thread that woke up run
for about one base slice (0.75 ms by default) before a busy neighbour may take the core
back, and it looks at the next scheduler tick (every 4 ms on this kernel, ``CONFIG_HZ=250``).
A live decoder's sample (~0.3 ms) fits in that; a camera frame (~2 ms: areas of 16
elements → force → displacement → decode) does not, and with both cores busy up to one
frame in ten waits a tick behind a neighbour (measured: p99 loaded/idle 1.5–2.1, p90
loaded 4–7 ms against a 2–3 ms median; ``benchmarks/test_bench_live.py``). Requesting
another fair slice (sched_setattr, 0.1–10 ms) did not help (1.8–3.4); a real-time policy
does (0.8–1.0).

:func:`realtime_priority` runs a block with the calling thread under ``SCHED_FIFO``
(with ``SCHED_RESET_ON_FORK``, so child processes such as the stage emulator start at the
normal policy) and restores the thread's policy afterwards. The thread must sleep
between samples, as the acquisition loop does; the kernel's real-time throttling
(``/proc/sys/kernel/sched_rt_runtime_us``, 95 % by default) still leaves other tasks
their share if it does not. It needs root, ``CAP_SYS_NICE`` or a real-time priority
limit (``ulimit -r``, e.g. ``@realtime - rtprio 20`` in ``/etc/security/limits.conf``);
without them the block runs at the normal policy and the reason is yielded.
"""
from __future__ import annotations

import os
from contextlib import contextmanager

from feeler.errors import ArgumentError

__all__ = ["realtime_priority", "DEFAULT_PRIORITY"]

DEFAULT_PRIORITY = 10       # SCHED_FIFO priority 1–99; low: above every fair task, below the kernel's own


@contextmanager
def realtime_priority(priority: int = DEFAULT_PRIORITY):
    """Run the block with the calling thread at ``SCHED_FIFO`` ``priority``.

    Yields None when granted, else one line saying why not (the block then runs at the
    thread's normal policy). The thread's earlier policy is restored on exit.

    Raises:
        ArgumentError: a priority outside 1–99.
    """
    if not (isinstance(priority, int) and 1 <= priority <= 99):
        raise ArgumentError("priority", priority, "an integer in 1..99 (SCHED_FIFO)")
    if not hasattr(os, "sched_setscheduler"):
        yield "real-time scheduling is not available on this system"
        return
    before = (os.sched_getscheduler(0), os.sched_getparam(0))
    refused = None
    try:
        level = min(priority, os.sched_get_priority_max(os.SCHED_FIFO))
        os.sched_setscheduler(0, os.SCHED_FIFO | os.SCHED_RESET_ON_FORK, os.sched_param(level))
    except PermissionError:
        refused = (f"real-time priority {priority} not permitted (needs root, CAP_SYS_NICE or a real-time "
                   f"priority limit: ulimit -r is {_rtprio_limit()})")
    except OSError as exc:
        refused = f"real-time priority {priority} refused by the system: {exc.strerror or exc}"
    if refused is not None:       # yielded outside the handler: errors of the block are not chained to it
        yield refused
        return
    try:
        yield None
    finally:
        os.sched_setscheduler(0, before[0], before[1])


def _rtprio_limit() -> str:
    try:
        import resource

        soft, _ = resource.getrlimit(resource.RLIMIT_RTPRIO)
        return "unlimited" if soft == resource.RLIM_INFINITY else str(soft)
    except (ImportError, AttributeError, OSError):
        return "unknown"
