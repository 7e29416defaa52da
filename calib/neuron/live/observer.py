"""Decode while acquiring: a campaign observer that feeds every sample to the live decoder
and keeps ``RUN/decisions.csv`` up to date (``feeler acquire --decode FIT``).

A scan's row is written when its ``scan_done`` event arrives — the moment it enters
``scans.csv`` — so ``decisions.csv`` always holds exactly the complete scans, like
``feeler decode RUN`` afterwards. An aborted attempt is dropped when the next begins, and
a scan cut by the end of the run is not written. On ``--resume`` the scans done before
(``RUN/scans.csv``, acquired with or without ``--decode``) are decoded first, as ``feeler
decode`` decodes them, so decisions.csv holds every complete scan of the run.
"""
from __future__ import annotations

from pathlib import Path

from feeler.hardware.acquire.progress import CampaignObserver

__all__ = ["DecodeObserver"]


class DecodeObserver(CampaignObserver):
    """Args:
        decoder (RunDecoder): the run decoder (its ``on_state``/``on_scan`` print, if set).
        out (Path): ``decisions.csv`` to keep written.
        say (callable | None): prints a note at the end (the batch's read-out noise reason,
            with which every scan is flagged, as ``feeler decode`` notes it); None: silent.
    """

    def __init__(self, decoder, out, say=None, tell=None):
        self.decoder, self.out, self.say, self.tell = decoder, Path(out), say, tell

    def started(self, scans_planned: int, scans_done: int, samples_per_scan: int) -> None:
        """On ``--resume``: decode the scans an earlier run completed (its ``scans.csv``),
        without a line per decision (``tell`` says how many in one line)."""
        if not scans_done:
            return
        import csv

        d = self.decoder
        callbacks, (d.on_state, d.on_scan) = (d.on_state, d.on_scan), (None, None)
        try:
            with open(self.out.parent / "scans.csv", newline="", encoding="utf-8") as f:
                for row in csv.DictReader(f):
                    d.sample(row)
            d.end_scan()
        finally:
            d.on_state, d.on_scan = callbacks
        d.write(self.out)
        if self.tell is not None:
            self.tell(f"decoded the {len(d.rows)} scan{'s' if len(d.rows) != 1 else ''} acquired before this resume "
                      f"into {self.out}; decoding the rest as they are acquired")

    def sample(self, row: dict) -> None:
        self.decoder.sample(row)

    def event(self, kind: str, fields: dict) -> None:
        if kind == "scan_done":
            self.decoder.end_scan()
            self.decoder.write(self.out)

    def finished(self, summary: dict) -> None:
        self.decoder.discard()
        self.decoder.write(self.out)
        if self.decoder.batch and self.say is not None:
            self.say(f"note: every scan is flagged: {self.decoder.batch}")


def decode_observer(fit_dir, run_dir, others=(), *, force: bool = False, seed: int = 0, n_draws: int = 400,
                    threshold: float = 0.9, accept_failed: bool = False, progress: bool = True) -> DecodeObserver:
    """The observer of ``acquire --decode``: loads and checks the fit (a failed fit is
    refused unless ``accept_failed``); with ``progress``, prints a line per decision on
    stderr (wiping the progress line of ``others`` first), as ``feeler decode`` does, and
    without it none (``--no-progress``, as ``feeler decode --no-progress``). The batch's
    note at the end is a result: on stdout either way.

    Raises:
        InputError: an unreadable or failed fit; an earlier decisions.csv without ``force``.
    """
    from feeler.calib.fit import load, require_ok
    from feeler.calib.neuron.live import LiveDecoder
    from feeler.calib.neuron.live.run import RunDecoder
    from feeler.calib.neuron.live.show import LiveView
    from feeler.errors import OverwriteError

    out = Path(run_dir) / "decisions.csv"
    if out.exists() and not force:
        raise OverwriteError(out)
    fit = require_ok(load(fit_dir), accept_failed=accept_failed, what="neuron calibration")
    live = LiveDecoder(fit, seed=seed, n_draws=n_draws, threshold=threshold)

    def wipe():
        for o in others:
            if hasattr(o, "clear"):
                o.clear()

    if not progress:
        return DecodeObserver(RunDecoder(live), out, say=print)
    view = LiveView(live.plates_mm, live=False, before_line=wipe)
    return DecodeObserver(RunDecoder(live, on_state=view.on_state, on_scan=view.on_scan), out, say=print,
                          tell=lambda text: view.line(f"feeler acquire: {text}"))
