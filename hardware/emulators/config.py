"""The emulated machine: Grbl 1.1h's default settings, with the machine's own values on top.

:data:`GRBL_DEFAULTS` is the ``$$`` table of a freshly flashed Grbl 1.1h (``defaults.h``):
500 mm/min and 10 mm/s² per axis, 200 mm of travel, 250 steps/mm, soft limits and homing
off. A :class:`GrblConfig` overrides the machine fields (rates, accelerations, travel) and
any other setting, e.g. ``settings=((22, 1),)`` for a board that boots locked because
homing is enabled.
"""
from __future__ import annotations

from dataclasses import dataclass

__all__ = ["GrblConfig", "GRBL_DEFAULTS", "INTEGER_SETTINGS"]

Vec = tuple[float, float, float]

#: Grbl 1.1h's ``$$`` after ``$RST=*`` (``defaults.h``, DEFAULTS_GENERIC)
GRBL_DEFAULTS: dict[int, float] = {
    0: 10, 1: 25, 2: 0, 3: 0, 4: 0, 5: 0, 6: 0, 10: 1, 11: 0.010, 12: 0.002, 13: 0, 20: 0, 21: 0,
    22: 0, 23: 0, 24: 25.0, 25: 500.0, 26: 250, 27: 1.0, 30: 1000.0, 31: 0.0, 32: 0,
    100: 250.0, 101: 250.0, 102: 250.0, 110: 500.0, 111: 500.0, 112: 500.0,
    120: 10.0, 121: 10.0, 122: 10.0, 130: 200.0, 131: 200.0, 132: 200.0}

#: settings Grbl stores and prints as integers (the others print with 3 decimals; $30/$31 none)
INTEGER_SETTINGS = frozenset({0, 1, 2, 3, 4, 5, 6, 10, 13, 20, 21, 22, 23, 26, 32})


@dataclass(frozen=True)
class GrblConfig:
    """Machine of the emulator.

    Attributes:
        travel_mm (tuple[float, float, float]): ``$130-132``; Grbl's soft limits, when
            enabled, are machine positions in ``[-travel, 0]``.
        max_rate_mm_min (tuple[float, float, float]): ``$110-112``, per-axis maximum rate.
        accel_mm_s2 (tuple[float, float, float]): ``$120-122``, per-axis acceleration.
        start_mm (tuple[float, float, float]): machine position at power-up, mm.
        settings (tuple[tuple[int, float], ...]): further ``$N`` values, e.g. ``((22, 1),)``.
        version (str): reported in the banner; ``build`` the date in ``$I``.
        rx_buffer_bytes (int): serial receive buffer (holds one byte less).
        planner_blocks (int): motion blocks planned ahead.
    """

    travel_mm: Vec = (200.0, 200.0, 200.0)
    max_rate_mm_min: Vec = (500.0, 500.0, 500.0)
    accel_mm_s2: Vec = (10.0, 10.0, 10.0)
    start_mm: Vec = (0.0, 0.0, 0.0)
    settings: tuple[tuple[int, float], ...] = ()
    version: str = "1.1h"
    build: str = "20190830"
    rx_buffer_bytes: int = 128
    planner_blocks: int = 15

    def table(self) -> dict[int, float]:
        """The ``$$`` table at power-up: Grbl's defaults, the machine fields, ``settings``."""
        table = dict(GRBL_DEFAULTS)
        for base, values in ((110, self.max_rate_mm_min), (120, self.accel_mm_s2), (130, self.travel_mm)):
            table.update({base + i: float(v) for i, v in enumerate(values)})
        table.update({int(k): v for k, v in self.settings})
        return {k: (int(v) if k in INTEGER_SETTINGS else float(v)) for k, v in table.items()}
