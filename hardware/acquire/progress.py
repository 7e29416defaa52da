"""Watching a campaign: the observer hooks, and the progress shown while it runs.

A :class:`CampaignObserver` is told when the campaign starts, of every sample as it is
written (the row of ``samples.csv``), of every journal event (scan start and end, bad
frames, bad lines, late samples) and of the final summary. :class:`~.store.RunStore`
calls the observers it holds, so anything that watches a run — :class:`Progress`, or a
live decoder of the samples — attaches without changing the campaign loop.

:class:`Progress` writes to a terminal one live line (scan i of n, samples, bad and late
samples, ETA), redrawn at most every ``interval_s`` (log warnings, e.g. of a late sample,
print on lines of their own: :meth:`Progress.clear` is a logging filter); to anything
else, one line per finished scan.
"""
from __future__ import annotations

import sys
import time

__all__ = ["CampaignObserver", "Progress", "format_duration"]


class CampaignObserver:
    """Hooks of a running campaign; every method is optional (the defaults do nothing)."""

    def started(self, scans_planned: int, scans_done: int, samples_per_scan: int) -> None:
        """The campaign starts (``scans_done`` already done by an earlier run)."""

    def sample(self, row: dict) -> None:
        """One sample, as written to ``samples.csv`` (keys: ``SAMPLE_COLUMNS``)."""

    def event(self, kind: str, fields: dict) -> None:
        """One journal event: ``scan_start``, ``scan_done``, ``bad_frame``, ``bad_line``, ..."""

    def finished(self, summary: dict) -> None:
        """The campaign ended (complete or not); ``summary`` as in ``summary.json``."""


def format_duration(seconds: float) -> str:
    """``1h02m``, ``4m05s`` or ``12s``."""
    seconds = int(round(seconds))
    hours, rest = divmod(seconds, 3600)
    minutes, secs = divmod(rest, 60)
    return f"{hours}h{minutes:02d}m" if hours else (f"{minutes}m{secs:02d}s" if minutes else f"{secs}s")


class Progress(CampaignObserver):
    """Progress on ``stream`` (default stderr): live on a terminal, a line per scan otherwise.

    Args:
        live (bool | None): force live (True) or per-scan lines (False); None: live when
            ``stream`` is a terminal.
        interval_s (float): least time between two redraws of the live line, seconds.
        clock: a monotonic clock (seconds).
    """

    def __init__(self, stream=None, live: bool | None = None, interval_s: float = 0.2, clock=time.monotonic):
        self.stream = sys.stderr if stream is None else stream
        self.live = bool(getattr(self.stream, "isatty", lambda: False)()) if live is None else live
        self.interval_s, self.clock = interval_s, clock
        self.planned = self.done = self.per_scan = self.samples = self.in_scan = 0
        self.bad = self.late = 0
        self.scan_id, self._start, self._last_draw, self._drawn = None, clock(), -1e9, 0
        self._first_done, self._last_done = 0, self._start

    def started(self, scans_planned: int, scans_done: int, samples_per_scan: int) -> None:
        self.planned, self.done, self.per_scan = scans_planned, scans_done, samples_per_scan
        self._first_done, self._start = scans_done, self.clock()
        self._last_done = self._start

    def eta_s(self) -> float | None:
        """Seconds left, from the scans finished in this run (None before the first): their
        mean time per scan for every scan not finished, less the time the current one has
        run. Timed from the clock alone, the live line's ETA rose through every scan (the
        time spent in it counted as if no scan were nearer its end)."""
        finished = self.done - self._first_done
        if finished <= 0:
            return None
        per_scan = (self._last_done - self._start) / finished
        return max(0.0, per_scan * (self.planned - self.done) - (self.clock() - self._last_done))

    def _eta(self) -> str:
        eta = self.eta_s()
        return "ETA --" if eta is None else f"ETA {format_duration(eta)}"

    def sample(self, row: dict) -> None:
        self.samples += 1
        self.in_scan += 1
        self.late += int(row.get("late", 0))
        self._draw()

    def event(self, kind: str, fields: dict) -> None:
        if kind == "scan_start":
            self.scan_id, self.in_scan = fields["scan_id"], 0
        elif kind in ("bad_frame", "bad_line"):
            self.bad += 1
        elif kind == "scan_done":
            self.done += 1
            self._last_done = self.clock()
            if self.live:
                self._draw(force=True)
            else:
                self._write(f"feeler acquire: scan {fields['scan_id']} done ({self.done} of {self.planned}): "
                            f"{fields['n_samples']} samples; so far {self.bad} bad, {self.late} late; {self._eta()}\n")

    def finished(self, summary: dict) -> None:
        if self.live and self._drawn:
            self._draw(force=True)
            self._write("\n")

    def line(self) -> str:
        """The live line."""
        scan = "-" if self.scan_id is None else self.scan_id
        return (f"scan {min(self.done + 1, self.planned)} of {self.planned} (id {scan}), sample "
                f"{self.in_scan} of {self.per_scan}; {self.samples} samples, {self.bad} bad, {self.late} late; "
                f"{self._eta()}")

    def clear(self, record=None) -> bool:
        """Wipe the live line (a ``logging`` filter: a warning then prints on a line of its
        own, and the next sample redraws the progress below it). Always True."""
        if self.live and self._drawn:
            self._write("\r" + " " * self._drawn + "\r")
            self._drawn, self._last_draw = 0, -1e9
        return True

    def _draw(self, force: bool = False) -> None:
        now = self.clock()
        if not self.live or (not force and now - self._last_draw < self.interval_s):
            return
        self._last_draw = now
        text = self.line()
        self._write("\r" + text + " " * max(self._drawn - len(text), 0))
        self._drawn = len(text)

    def _write(self, text: str) -> None:
        self.stream.write(text)
        self.stream.flush()
