"""Decode a run's samples as they come, scan after scan, into the rows of ``decisions.csv``.

:class:`RunDecoder` takes sample rows (dicts with ``scan_id``, ``t_s``, ``uy_mm`` and
optionally ``x_mm``, ``attempt``, ``step_mm``, ``speed_mm_s``, as ``samples.csv`` holds
them). A new ``scan_id`` closes the scan before it; a new ``attempt`` of the scan in
progress drops the earlier attempt unreported (the acquisition retries a scan from its
start, and a resumed run starts again at the scan it was stopped in), and a later attempt
of a scan closed before replaces its row.

Columns of ``decisions.csv`` (:data:`COLUMNS`, with one ``p_<plate>mm`` per plate):
``scan_id``; ``step_mm`` when the samples are labelled; ``p_<plate>mm`` and ``height_mm``,
``lo90_mm``, ``hi90_mm`` at the end of the scan (equal to ``feeler classify``'s);
``decided_mm``, ``p_decided``, ``decided_at_t_s``, ``decided_at_x_mm`` of the decision
(empty when the scan ended undecided); ``n_samples``; ``flagged`` and ``flag`` (why the scan
lies outside the fit's training envelope).
"""
from __future__ import annotations

import math

import numpy as np

from feeler.calib.neuron.live.table import plate_column

__all__ = ["RunDecoder", "decision_columns"]


def decision_columns(plates_mm, *, labelled: bool) -> list[str]:
    """The columns of ``decisions.csv`` in order."""
    return (["scan_id"] + (["step_mm"] if labelled else []) + [plate_column(v) for v in plates_mm]
            + ["decided_mm", "p_decided", "height_mm", "lo90_mm", "hi90_mm", "decided_at_t_s", "decided_at_x_mm",
               "n_samples", "flagged", "flag"])


def _num(row: dict, key: str) -> float | None:
    v = row.get(key)
    if v is None or v == "":
        return None
    v = float(v)
    return None if math.isnan(v) else v


class RunDecoder:
    """Scan-by-scan driver of a :class:`~feeler.calib.neuron.live.LiveDecoder`.

    Args:
        live (LiveDecoder): the decoder (reset at each scan).
        on_state (callable | None): ``on_state(scan_id, state, z_history)`` after every sample.
        on_scan (callable | None): ``on_scan(row)`` when a scan's row is complete.
    """

    def __init__(self, live, *, on_state=None, on_scan=None):
        self.live, self.on_state, self.on_scan = live, on_state, on_scan
        self.rows: dict[int, dict] = {}
        self.snapped: dict[int, bool | None] = {}      # each scan's mode as read at its end (None: one-mode fit)
        self.off_plate: dict[int, bool] = {}             # each scan read off every trained plate at its end
        self._key = None
        self._labels: dict = {}
        self.labelled = False

    def sample(self, row: dict):
        """One sample row; returns the decoder's state after it."""
        sid = int(float(row["scan_id"]))
        key = (sid, row.get("attempt"))
        if key != self._key:
            if self._key is not None and self._key[0] == sid:
                self.discard()              # a new attempt of the scan in progress: the earlier one was aborted
            else:
                self.end_scan()
            self._key = key
            self._labels = {"step_mm": _num(row, "step_mm"), "speed_mm_s": _num(row, "speed_mm_s")}
            self.live.reset(speed_mm_s=self._labels["speed_mm_s"])
        x = _num(row, "x_mm")
        state = self.live.push(float(row["t_s"]), float(row["uy_mm"]), x_mm=x)
        if self.on_state is not None:
            self.on_state(sid, state)
        return state

    def end_scan(self) -> dict | None:
        """Close the scan in progress (at the end of a run, or when it is known complete)."""
        if self._key is None:
            return None
        end = self.live.finish()
        sid, self._key = self._key[0], None
        if end.new_decision and self.on_state is not None:
            self.on_state(sid, end)
        d = end.decision
        step = self._labels.get("step_mm")
        self.labelled |= step is not None
        row = {"scan_id": sid, "step_mm": np.nan if step is None else step,
               **{plate_column(v): float(p) for v, p in zip(self.live.plates_mm, end.prob)},
               "decided_mm": np.nan if d is None else d.plate_mm, "p_decided": np.nan if d is None else d.p,
               "height_mm": end.height_mm, "lo90_mm": end.lo90_mm, "hi90_mm": end.hi90_mm,
               "decided_at_t_s": np.nan if d is None else d.t_s, "decided_at_x_mm": np.nan if d is None else d.x_mm,
               "n_samples": end.n, "flagged": bool(end.flags), "flag": "; ".join(end.flags)}
        self.rows[sid] = row
        self.snapped[sid] = self.live.snapped
        self.off_plate[sid] = self.live.off_plate
        if self.on_scan is not None:
            self.on_scan(row)
        return row

    @property
    def in_progress(self) -> int | None:
        """The scan id of the scan in progress (samples taken, not closed), else None."""
        return None if self._key is None else self._key[0]

    def discard(self) -> None:
        """Forget the scan in progress (cut short: it gets no row)."""
        self._key = None

    def table(self):
        """The rows so far as a DataFrame in ``decisions.csv`` order (by scan_id)."""
        import pandas as pd

        cols = decision_columns(self.live.plates_mm, labelled=self.labelled)
        rows = [self.rows[k] for k in sorted(self.rows)]
        return pd.DataFrame(rows, columns=list(rows[0]) if rows else cols)[cols]

    def write(self, path) -> None:
        """Write ``decisions.csv`` atomically (a reader never sees half a file)."""
        import os

        tmp = f"{path}.tmp"
        self.table().to_csv(tmp, index=False)
        os.replace(tmp, path)
