"""Checks every command runs on its output path before any work (issue 16 items 3, 4).

A fit that runs for minutes and then cannot write its result has wasted the user's
time: ``--out`` at an existing file, in a read-only or immutable directory, or at an
earlier result without ``--force`` is refused first, in one line.
"""
from __future__ import annotations

import os
import tempfile
from pathlib import Path

from feeler.errors import ArgumentError, OverwriteError

__all__ = ["check_out_dir"]


def check_out_dir(out: str | os.PathLike, files=(), *, force: bool = False, name: str = "--out") -> Path:
    """Refuse ``out`` unless it is (or can become) a writable directory; nothing is created.

    Args:
        out: the output directory a command will write.
        files (iterable of str): file names the command writes into ``out``; one that
            already exists is refused unless ``force``.
        force (bool): overwriting earlier results is allowed.
        name (str): the argument, for the message.

    Raises:
        ArgumentError: ``out`` (or a parent) is a file, or the directory that would hold
            the output is not writable (read-only, immutable, no permission).
        OverwriteError: one of ``files`` exists in ``out`` and not ``force``.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ArgumentError(name, str(out), "a directory to write into, not an existing file")
    if out.is_dir() and not force:
        for f in files:
            if (out / f).exists():
                raise OverwriteError(out / f)
    probe_in = out
    while not probe_in.exists():                     # the nearest existing ancestor
        if probe_in.parent == probe_in:
            break
        probe_in = probe_in.parent
    if not probe_in.is_dir():
        raise ArgumentError(name, str(out), f"a directory path, but {probe_in} is a file")
    try:                                             # os.access says yes to root on read-only mounts
        fd, probe = tempfile.mkstemp(prefix=".feeler-write-check-", dir=probe_in)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        why = exc.strerror or type(exc).__name__
        raise ArgumentError(name, str(out), f"a directory feeler can write into ({probe_in}: {why})") from None
    return out


# Upper bounds of the size-like options, checked before any work (an outside audit: --n-tau
# 100000000 ran 300 s without a line, --draws 1000000000 was a numpy MemoryError traceback,
# after 55 s of work for calibrate neuron). Each is far above what a fit needs, and below
# what a lab machine's memory holds: calibrate neuron's grid posterior of four plates at
# 200 000 draws in all holds 1.3 GB (sensor 0.2 GB, psychophysics 0.3 GB).
MAX_CHAINS = 64
MAX_TOTAL_DRAWS = 200_000          # chains × draws: 50 times the default 4 × 1000
MAX_TUNE = 100_000                 # warm-up steps per chain: 100 times the default
MAX_N_TAU = 1_000                  # finger-route τ nodes on 1 ms–10 s: 0.9 % apart; 121 by default
MAX_N_SCANS = 20_000               # discriminate's touches per height: 20 times the default
MAX_EMCEE_STEPS = 200_000          # the cap of an emcee run to convergence
MAX_SBC_N = 10_000                 # validate sbc datasets, each one fit: 50 times the default
#: sizes a command checks itself (validate sbc's --draws are thinned draws of each fit, 9-999)
OWN_SIZES = {"validate sbc": ("draws",)}

__all__ += ["refuse_unused", "MAX_CHAINS", "MAX_TOTAL_DRAWS", "MAX_TUNE", "MAX_N_TAU", "MAX_N_SCANS", "MAX_EMCEE_STEPS",
            "MAX_SBC_N", "max_workers", "check_sizes", "SIZES_HELP"]

#: what --help says of the sampler sizes
SIZES_HELP = (f"at most {MAX_CHAINS} chains and {MAX_TOTAL_DRAWS} draws in all (chains × draws), "
              f"{MAX_TUNE} warm-up steps")


def max_workers() -> int:
    """LocalCluster worker processes allowed: this machine's CPUs (at least 2, the default)."""
    return max(2, os.cpu_count() or 1)


def _int(value) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def check_sizes(args, *, chains_name: str = "chains") -> None:
    """Refuse a size-like option beyond its upper bound (the ``MAX_*`` of this module), before
    any work: the arrays it asks for would not fit in memory, or the run would not end.

    Args:
        args: the parsed command line; options it does not have are skipped.
        chains_name (str): the option whose value multiplies --draws.

    Raises:
        ArgumentError: the option, its value and the allowed range, in one line.
    """
    own = OWN_SIZES.get(getattr(args, "command", None) or "", ())
    for name, top in (("chains", MAX_CHAINS), ("tune", MAX_TUNE), ("n_tau", MAX_N_TAU), ("n_scans", MAX_N_SCANS),
                      ("emcee_steps", MAX_EMCEE_STEPS), ("n", MAX_SBC_N)):
        value = getattr(args, name, None)
        if name not in own and _int(value) and value > top:
            raise ArgumentError(f"--{name.replace('_', '-')}", value, f"at most {top}" if name != "tune" else
                                f"at most {top} warm-up steps per chain")
    workers, most = getattr(args, "workers", None), max_workers()
    if _int(workers) and workers > most:
        raise ArgumentError("--workers", workers, f"at most {most}, this machine's CPUs (a worker process each; "
                            f"more only share them and each holds its own libraries in memory)")
    draws, chains = getattr(args, "draws", None), getattr(args, chains_name, None)
    if chains is None and hasattr(args, chains_name):
        return                  # chains per backend: the command checks again once it has filled them in
    if "draws" not in own and _int(draws):
        chains = chains if _int(chains) and chains >= 1 else 1
        if draws * chains > MAX_TOTAL_DRAWS:
            raise ArgumentError("--draws", draws, f"at most {MAX_TOTAL_DRAWS // chains} with {chains} chains: "
                                f"chains × draws at most {MAX_TOTAL_DRAWS} (the posterior draws must fit in memory)")


def refuse_unused(args, defaults: dict, *, used: bool, needs) -> None:
    """Refuse an option of ``defaults`` (name -> default) typed where it would not be used
    (``used`` False), in one line saying what it ``needs(name)``; then fill in the defaults of
    those not typed. Such options default to None (store_true ones to False), so that a
    typed value can be told from the default (an outside audit: --wait-s without --follow,
    --target-accept with the exact grid ran and exited 0, the option silently ignored)."""
    from feeler.errors import ArgumentError

    for name, default in defaults.items():
        value = getattr(args, name)
        if value is not None and value is not False and not used:
            raise ArgumentError(f"--{name.replace('_', '-')}", None if value is True else value, needs(name))
        if value is None:
            setattr(args, name, default)
