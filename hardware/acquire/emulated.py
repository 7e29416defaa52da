"""The Grbl emulator of ``feeler acquire --emulate``: a fast stage in a child process.

It is :func:`feeler.hardware.emulators.emulator_process` (spawned, serving a real pty, tied
to its parent so that a campaign killed with ``kill -9`` leaves no emulator behind) with
the quick machine :data:`FAST_STAGE`.
"""
from __future__ import annotations

import contextlib
from typing import Iterator

from feeler.hardware.emulators import GrblConfig, emulator_process

__all__ = ["campaign_emulator", "FAST_STAGE"]

#: the emulated machine of ``feeler acquire --emulate``: a quick desktop stage (all axes
#: 6000 mm/min, 2000 mm/s², travel 200 × 200 × 50 mm) so that emulated campaigns run fast
FAST_STAGE = GrblConfig(max_rate_mm_min=(6000.0, 6000.0, 6000.0), accel_mm_s2=(2000.0, 2000.0, 2000.0))


@contextlib.contextmanager
def campaign_emulator(config: GrblConfig = FAST_STAGE, faults: tuple = (),
                      start_timeout_s: float = 30.0) -> Iterator[str]:
    """Run a Grbl emulator (with injected ``faults``, :class:`~feeler.hardware.emulators.Fault`)
    in a child process; yields its pty device path.

    Start it at the plan's first position with ``dataclasses.replace(FAST_STAGE, start_mm=...)``.
    """
    with emulator_process(config, tuple(faults), seed=0, start_timeout_s=start_timeout_s) as emu:
        yield emu.path
