"""How many threads a parallel loop of the neuron core may use, decided per call.

A parallel loop ends when its last thread ends. When another process holds a core, the
thread that shares it waits for the scheduler's next slice (milliseconds), and a loop
of a millisecond or less takes tens of milliseconds instead — measured here for
``pulse_density`` on 5·10⁵ samples: 1.4 ms on one thread, a 17–116 ms median on two
with the machine busy. So each call first counts the cores that are free now and runs
on that many threads (serially when one or none is), and only when there is enough
work (:data:`PARALLEL_MIN_SAMPLES`) for a second thread to pay for its start.

"Free now" is the CPUs this process may run on (its affinity mask) minus the other
tasks runnable at this instant — the kernel's ``nr_running``, the first number of the
fourth field of ``/proc/loadavg`` (read in ~10 µs; it counts this thread too). It is
instantaneous, not the 1-minute load average: a busy loop that starts or stops is
seen by the next call. Where ``/proc/loadavg`` cannot be read, the 1-minute load
average stands in. The OpenMP worker threads numba starts are told to sleep, not spin,
between loops (``OMP_WAIT_POLICY=PASSIVE`` unless the user set it), so that our own
idle workers neither hold a core nor count as runnable. ``FEELER_NEURON_THREADS=N``
pins the count instead (a machine that runs nothing else).
"""
from __future__ import annotations

import math
import os

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")   # before numba's OpenMP pool starts

import numba as nb  # noqa: E402

__all__ = ["PARALLEL_MIN_SAMPLES", "ENV", "free_cpus", "pinned", "threads_for", "run_parallel"]

# a positive integer pins the thread count (a dedicated machine); unset or "auto": per call
ENV = "FEELER_NEURON_THREADS"

# below this many samples in a call one thread is faster (measured idle: 10⁴ samples 36 µs
# on one thread and on two; 10⁵: 0.19 ms on one, 0.13 ms on two)
PARALLEL_MIN_SAMPLES = 1 << 16

_LOADAVG = "/proc/loadavg"


def _affinity() -> int:
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


_fd: list[int] = []    # /proc/loadavg kept open: pread at 0 re-reads it (no open/close per call)


def _others_running() -> float:
    """Tasks other than this thread that are runnable now."""
    try:
        if not _fd:
            _fd.append(os.open(_LOADAVG, os.O_RDONLY))
        running = int(os.pread(_fd[0], 128, 0).split()[3].split(b"/")[0])
        return max(running - 1, 0)
    except (OSError, ValueError, IndexError):
        try:
            return os.getloadavg()[0]
        except (AttributeError, OSError):
            return 0.0


def free_cpus() -> int:
    """CPUs of this process's affinity mask that no other runnable task holds now (≥ 1)."""
    return max(1, _affinity() - math.ceil(_others_running()))


def pinned() -> int | None:
    """The thread count pinned by ``FEELER_NEURON_THREADS`` (a positive integer), or
    None when it is unset or ``auto`` (count the free cores per call).

    Raises:
        ArgumentError: any other value.
    """
    text = os.environ.get(ENV, "auto").strip()
    if text in ("", "auto"):
        return None
    if not text.isdigit() or int(text) < 1:
        from feeler.errors import ArgumentError
        raise ArgumentError(ENV, text, "a positive integer or 'auto' (threads by the cores free per call)")
    return int(text)


def threads_for(samples: int, rows: int | None = None) -> int:
    """Threads for a loop of ``samples`` samples in all over ``rows`` independent rows
    (None: a record cut into pieces): 1 below :data:`PARALLEL_MIN_SAMPLES` or for one
    row, else the free CPUs (or the pinned count), at most numba's thread count and
    ``rows``."""
    if samples < PARALLEL_MIN_SAMPLES or (rows is not None and rows < 2):
        return 1
    want = pinned() or free_cpus()
    return max(1, min(want, nb.get_num_threads(), rows or samples))


def run_parallel(fn, threads: int, *args):
    """``fn(*args)`` (a ``parallel=True`` numba function) on ``threads`` threads."""
    before = nb.get_num_threads()
    if threads == before:
        return fn(*args)
    nb.set_num_threads(threads)
    try:
        return fn(*args)
    finally:
        nb.set_num_threads(before)
