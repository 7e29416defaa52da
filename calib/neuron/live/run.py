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

The batch's read-out noise is judged as ``feeler classify`` judges it
(:meth:`~.envelope.Envelope.batch_noise` over every scan closed so far, then
:func:`~.envelope.with_batch`), again after every scan: once the scans so far show a
set-up noisier or far quieter than the training scans, every row so far is flagged with
that reason (a decision taken before does not hold) and the scans after it are flagged
from their first sample (so not decided); should later scans bring the batch back inside,
the rows lose that flag again. At the end of a run the flags are those classify gives
the same scans.
"""
from __future__ import annotations

import math

import numpy as np

from feeler.calib.neuron.live.table import plate_column

__all__ = ["RunDecoder", "decision_columns", "scan_key"]


def scan_key(uy_mm) -> bytes:
    """A scan's U_y at every sample, as :func:`~.table.copies_note` compares scans."""
    import hashlib

    return hashlib.blake2b(np.ascontiguousarray(np.asarray(uy_mm, float)).tobytes(), digest_size=16).digest()


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
        self.own: dict[int, tuple] = {}                  # each scan's own flags and its noise reason
        self.uy_key: dict[int, bytes] = {}               # each scan's U_y, as copies_note compares them
        self.batch: str | None = None                    # the batch's read-out noise reason, if any
        self._noise = np.full(64, np.nan)                # each closed scan's read-out noise (mm), in a slot
        self._slot: dict[int, int] = {}                  # of its own (a run of 20 000 scans: no list rebuilt)
        self._used = 0
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
        self.own[sid] = (self.live.own_flags, self.live.own_noise)
        self.uy_key[sid] = scan_key(self.live.uy_mm)
        self._keep_noise(sid, self.live.noise_mm)
        self.judge_batch()
        self._flag(sid)
        if self.on_scan is not None:
            self.on_scan(row)
        return row

    def _keep_noise(self, sid: int, noise_mm: float) -> None:
        i = self._slot.get(sid)
        if i is None:                                   # a new scan (a later attempt reuses its slot)
            if self._used == self._noise.size:
                self._noise = np.concatenate([self._noise, np.full(self._noise.size, np.nan)])
            i = self._slot[sid] = self._used
            self._used += 1
        self._noise[i] = noise_mm

    def judge_batch(self) -> str | None:
        """Judge the read-out noise of the scans closed so far as a batch, as classify does
        (:meth:`~.envelope.Envelope.batch_noise`); the live decoder flags the next scans with
        the reason, and every row gets it when the table is made (:meth:`table`). Returns the
        reason, or None."""
        self.batch = self.live.env.batch_noise(self._noise[:self._used])
        self.live.batch = self.batch
        return self.batch

    def _flag(self, sid: int) -> None:
        """Scan ``sid``'s row flagged as judged with the batch (:func:`~.envelope.with_batch`);
        a row read back from an earlier decisions.csv (its own flags unknown) keeps its flags."""
        from feeler.calib.neuron.live.envelope import with_batch

        if sid in self.own:
            flags = with_batch(*self.own[sid], self.batch)
            self.rows[sid]["flagged"], self.rows[sid]["flag"] = bool(flags), "; ".join(flags)

    def forget(self, sid: int) -> None:
        """Drop scan ``sid``'s row and what is kept of it (cut short: it gets no row)."""
        for kept in (self.rows, self.snapped, self.off_plate, self.own, self.uy_key):
            kept.pop(sid, None)
        i = self._slot.pop(sid, None)
        if i is not None:
            self._noise[i] = np.nan                     # not in the batch (batch_noise drops NaN)
        self.judge_batch()

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
        for k in self.rows:                             # every row with the batch as judged now
            self._flag(k)
        rows = [self.rows[k] for k in sorted(self.rows)]
        return pd.DataFrame(rows, columns=list(rows[0]) if rows else cols)[cols]

    def write(self, path) -> None:
        """Write ``decisions.csv`` atomically (a reader never sees half a file)."""
        import os

        tmp = f"{path}.tmp"
        self.table().to_csv(tmp, index=False)
        os.replace(tmp, path)
