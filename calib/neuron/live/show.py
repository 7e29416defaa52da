"""What a person watching a live decode sees.

On a terminal (``live=True``): one line for the scan in progress, rewritten at most every
``every_s`` seconds and at once when the decision is made — the decoded response z so far,
the probability of each plate, the decision — and kept when the scan ends. Elsewhere
(a log, a pipe): one line per decision and one per scan that ends undecided or flagged.
"""
from __future__ import annotations

import math
import sys
import time

from feeler.calib.neuron.live.table import plate_column

__all__ = ["LiveView"]


class LiveView:
    """Callbacks for :class:`~feeler.calib.neuron.live.run.RunDecoder` that print.

    Args:
        plates_mm (ndarray[C]): the fit's plates, mm.
        stream: text stream (default stderr). live (bool | None): rewrite one line (None:
            when ``stream`` is a terminal). every_s (float): least seconds between rewrites.
    """

    def __init__(self, plates_mm, *, stream=None, live: bool | None = None, every_s: float = 0.1,
                 clock=time.monotonic, before_line=None):
        self.plates = [float(v) for v in plates_mm]
        self.stream = stream or sys.stderr
        self.live = self.stream.isatty() if live is None else bool(live)
        self.every_s, self.clock = every_s, clock
        self._last = -math.inf
        self._width = 0
        self.before_line = before_line

    def _probs(self, prob) -> str:
        return " ".join(f"{v:g}:{p:.2f}" for v, p in zip(self.plates, prob))

    def on_state(self, scan_id: int, state) -> None:
        d = state.decision
        if not self.live:
            if state.new_decision:
                self.line(f"scan {scan_id}: decided {d.plate_mm:g} mm (p {d.p:.3f}) at t {d.t_s:.3f} s"
                           + ("" if math.isnan(d.x_mm) else f", x {d.x_mm:.3f} mm") + f", sample {d.index}")
            return
        now = self.clock()
        if not state.new_decision and now - self._last < self.every_s:
            return
        self._last = now
        text = (f"scan {scan_id}  z {state.z_mm:.4g} mm  p [{self._probs(state.prob)}]  "
                + (f"decided {d.plate_mm:g} mm at {d.t_s:.2f} s" if d else "deciding…")
                + (f"  FLAG {state.flags[0]}" if state.flags else ""))
        self.stream.write("\r" + text.ljust(self._width))
        self._width = len(text)
        self.stream.flush()

    def on_scan(self, row: dict) -> None:
        sid = row["scan_id"]
        probs = [row[plate_column(v)] for v in self.plates]
        end = (f"scan {sid}: end p [{self._probs(probs)}], height {row['height_mm']:.3g} mm "
               f"[{row['lo90_mm']:.3g}, {row['hi90_mm']:.3g}]"
               + ("" if not math.isnan(row["decided_mm"]) else ", undecided")
               + (f"; flagged: {row['flag']}" if row["flagged"] else ""))
        if self.live:
            self.stream.write("\r" + " " * self._width + "\r")
            self._width = 0
            self._last = -math.inf
            self.line(end)
        elif row["flagged"] or math.isnan(row["decided_mm"]):
            self.line(end)

    def line(self, text: str) -> None:
        """Print one line of its own (wiping a progress line first, if asked to)."""
        if self.before_line is not None:
            self.before_line()
        self.stream.write(text + "\n")
        self.stream.flush()
