"""The emulated machine: travel, rates, accelerations and the ``$$`` settings table."""
from __future__ import annotations

from dataclasses import dataclass

__all__ = ["GrblConfig"]

Vec = tuple[float, float, float]


@dataclass(frozen=True)
class GrblConfig:
    """Machine of the emulator (Grbl settings ``$130-132``, ``$110-112``, ``$120-122``).

    Attributes:
        travel_mm (tuple[float, float, float]): soft limits are ``[0, travel]`` per axis.
        max_rate_mm_min (tuple[float, float, float]): per-axis maximum rate, mm/min.
        accel_mm_s2 (tuple[float, float, float]): per-axis acceleration, mm/s².
        start_mm (tuple[float, float, float]): machine position at power-up, mm.
        version (str): reported in the banner.
        rx_buffer_bytes (int): serial receive buffer (holds one byte less).
        planner_blocks (int): motion blocks planned ahead.
    """

    travel_mm: Vec = (200.0, 200.0, 50.0)
    max_rate_mm_min: Vec = (3000.0, 3000.0, 1000.0)
    accel_mm_s2: Vec = (500.0, 500.0, 200.0)
    start_mm: Vec = (0.0, 0.0, 0.0)
    version: str = "1.1h"
    rx_buffer_bytes: int = 128
    planner_blocks: int = 15

    def settings(self) -> dict[int, float]:
        """The ``$$`` table (Grbl defaults except the machine fields above)."""
        table = {0: 10, 1: 25, 2: 0, 3: 0, 4: 0, 5: 0, 6: 0, 10: 1, 11: 0.010, 12: 0.002,
                 13: 0, 20: 1, 21: 0, 22: 1, 23: 0, 24: 25.0, 25: 500.0, 26: 250, 27: 1.0,
                 30: 1000, 31: 0, 32: 0, 100: 250.0, 101: 250.0, 102: 250.0}
        for base, values in ((110, self.max_rate_mm_min), (120, self.accel_mm_s2),
                             (130, self.travel_mm)):
            table.update({base + i: float(v) for i, v in enumerate(values)})
        return table
