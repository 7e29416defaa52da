"""The Grbl emulator of ``feeler acquire --emulate``: a fast stage in a child process.

It is :func:`feeler.hardware.emulators.emulator_process` (spawned, serving a real pty, tied
to its parent so that a campaign killed with ``kill -9`` leaves no emulator behind) with
the quick machine :data:`FAST_STAGE`, powered up over the plan's first plate.
"""
from __future__ import annotations

import contextlib
import dataclasses
from typing import Iterator

from feeler.hardware.emulators import GrblConfig, emulator_process

from .plan import moves_of, scans_of

__all__ = ["campaign_emulator", "emulated_stage", "FAST_STAGE"]

#: the emulated machine of ``feeler acquire --emulate``: a quick desktop stage (all axes
#: 6000 mm/min, 2000 mm/s², travel 200 mm, 1000 steps/mm) so that emulated campaigns run
#: fast and report positions to 1 µm; otherwise Grbl 1.1h's defaults
FAST_STAGE = GrblConfig(max_rate_mm_min=(6000.0,) * 3, accel_mm_s2=(2000.0,) * 3,
                        settings=((100, 1000.0), (101, 1000.0), (102, 1000.0)))


def emulated_stage(plan, config: GrblConfig = FAST_STAGE) -> GrblConfig:
    """``config`` powered up over the plan's first plate (clipped into ``[-travel, 0]``)."""
    start = moves_of(plan, scans_of(plan)[0])[1][1]
    return dataclasses.replace(config, start_mm=tuple(min(max(v, -t), 0.0) for v, t in zip(start, config.travel_mm)))


@contextlib.contextmanager
def campaign_emulator(config: GrblConfig = FAST_STAGE, faults: tuple = (),
                      start_timeout_s: float = 30.0) -> Iterator[str]:
    """Run a Grbl emulator (with injected ``faults``, :class:`~feeler.hardware.emulators.Fault`)
    in a child process; yields its pty device path."""
    with emulator_process(config, tuple(faults), seed=0, start_timeout_s=start_timeout_s) as emu:
        yield emu.path
