"""The run directory of a campaign, written so that ``kill -9`` loses at most one sample.

Files (all appended line by line, each line flushed and ``fsync``-ed before the next
sample is taken):

- ``samples.csv``: every sample as it arrives, of every attempt (:data:`SAMPLE_COLUMNS`);
- ``scans.csv``: the complete scans only, in ``feeler simulate``'s format plus extra
  columns (:data:`SCAN_COLUMNS`) — what ``feeler calibrate neuron`` reads at any time;
- ``journal.jsonl``: one JSON event per line (run start, scan start, bad frame, bad line,
  late sample, scan done): which scans are done, and the counts of ``summary.json``;
- ``scene.toml``: a byte copy of the plan (its ``[neuron]`` table serves ``calibrate``);
- ``layout.toml``: a byte copy of the plan's camera layout file, if it names one: the
  plan's copy refers to it by a path relative to the plan, which the run directory does
  not reach, so ``--resume --plan RUN/scene.toml`` reads this one;
- ``summary.json``: the counts, rewritten atomically after every scan.

A scan is complete when its ``scan_done`` event is in the journal. On resume a line cut
by the crash (the sample in flight) is dropped and counted, and ``scans.csv`` is rebuilt
from the complete scans, so a scan written but not yet journalled is not doubled.

One process writes a run directory at a time: :meth:`RunStore.create` and
:meth:`RunStore.resume` take its lock (:mod:`.lock`) before reading or changing anything;
the store's observers (:class:`~.progress.CampaignObserver`) see every sample and event.
"""
from __future__ import annotations

import json
import os
import shutil
from collections import Counter
from pathlib import Path

from feeler.errors import ArgumentError, DataFileError
from feeler.rundir import prepare_out_dir, write_json
from feeler.simulate import CSV_COLUMNS

from .lock import lock_run_dir, release_run_dir

__all__ = ["SCAN_COLUMNS", "SAMPLE_COLUMNS", "RunStore"]

EXTRA = ("repeat", "t_sched_s", "status_rtt_s", "late", "t_frame_s", "stage_x_mm", "stage_y_mm", "stage_z_mm", "area0_px2", "area1_px2",
         "area2_px2", "area3_px2", "fx_n", "fy_n", "fz_n")
SCAN_COLUMNS = CSV_COLUMNS + EXTRA
SAMPLE_COLUMNS = SCAN_COLUMNS + ("attempt",)
FILES = ("scene.toml", "samples.csv", "scans.csv", "journal.jsonl", "summary.json", "truth.json", "layout.toml")


def _append(path: Path, text: str) -> None:
    with open(path, "a", encoding="utf-8") as f:
        f.write(text)
        f.flush()
        os.fsync(f.fileno())


def _format(row: dict, columns) -> str:
    return ",".join(repr(float(row[c])) if isinstance(row[c], float) else str(row[c]) for c in columns) + "\n"


def _drop_partial_line(path: Path) -> int:
    """Cut a last line without its newline (written when the process died); 1 if cut."""
    data = path.read_bytes()
    if not data or data.endswith(b"\n"):
        return 0
    with open(path, "r+b") as f:
        f.truncate(data.rfind(b"\n") + 1)
        f.flush()
        os.fsync(f.fileno())
    return 1


class RunStore:
    """Append-only writer of one run directory; use :meth:`create` or :meth:`resume`."""

    def __init__(self, out: Path, lock_fd: int | None = None):
        self.out = Path(out)
        self.done: set[int] = set()
        self.counts: Counter = Counter()
        self.attempts: Counter = Counter()
        self.observers: list = []
        self._lock_fd = lock_fd

    @classmethod
    def create(cls, out, plan_path: str | Path, *, force: bool = False,
               layout_path: str | Path | None = None) -> "RunStore":
        """A new run directory, locked for this process (refuses to overwrite an earlier
        run without ``force``; with it, the earlier run's files and ``video/`` are removed).

        Raises:
            RunLocked: another process writes ``out``. OverwriteError: an earlier run.
        """
        fresh = not Path(out).exists()
        fd = lock_run_dir(out)
        try:
            out = prepare_out_dir(out, FILES + ("video",), force=force)
        except BaseException:
            release_run_dir(fd)
            if fresh:
                shutil.rmtree(out, ignore_errors=True)
            raise
        for name in FILES[1:]:
            (out / name).unlink(missing_ok=True)
        shutil.rmtree(out / "video", ignore_errors=True)
        shutil.copyfile(plan_path, out / "scene.toml")
        if layout_path is not None:
            shutil.copyfile(layout_path, out / "layout.toml")
        store = cls(out, fd)
        for name, cols in (("samples.csv", SAMPLE_COLUMNS), ("scans.csv", SCAN_COLUMNS)):
            _append(out / name, ",".join(cols) + "\n")
        store.event("run", resume=False)
        return store

    @classmethod
    def resume(cls, out, plan_path: str | Path) -> "RunStore":
        """Reopen ``out`` written by an interrupted run of the same plan, locked for this
        process (RunLocked if another process writes it)."""
        out = Path(out)
        for name in ("scene.toml", "journal.jsonl", "samples.csv", "scans.csv"):
            if not (out / name).is_file():
                raise DataFileError(out / name, "missing: not a run directory to --resume")
        fd = lock_run_dir(out)
        try:
            if (out / "scene.toml").read_bytes() != Path(plan_path).read_bytes():
                raise ArgumentError("--plan", str(plan_path),
                                    f"differs from the plan this run was started with; to continue the run, "
                                    f"pass --plan {out / 'scene.toml'} (its copy of that plan), or drop --resume "
                                    f"and give a new --out to start a run of this plan")
            return cls._reopen(out, fd)
        except BaseException:
            release_run_dir(fd)
            raise

    @classmethod
    def _reopen(cls, out: Path, fd: int) -> "RunStore":
        journal = out / "journal.jsonl"
        store = cls(out, fd)
        dropped = _drop_partial_line(out / "samples.csv") + _drop_partial_line(journal)
        for number, line in enumerate(journal.read_text(encoding="utf-8").splitlines(), 1):
            try:
                store._account(json.loads(line))
            except (json.JSONDecodeError, KeyError, TypeError):
                raise DataFileError(journal, f"line {number} is not a journal event") from None
        store.counts["partial_lines_dropped"] += dropped
        store._rebuild_scans()
        store.event("run", resume=True, partial_lines_dropped=dropped)
        return store

    def _account(self, ev: dict) -> None:
        kind = ev["event"]
        if kind == "scan_start":
            self.attempts[ev["scan_id"]] += 1
        elif kind == "scan_done":
            self.done.add(ev["scan_id"])
            self.counts["samples_written"] += ev["n_samples"]
        elif kind in ("bad_frame", "bad_line", "late_sample", "slow_scan"):
            self.counts[kind + "s"] += 1
        elif kind == "run":
            self.counts["runs"] += 1
            self.counts["partial_lines_dropped"] += ev.get("partial_lines_dropped", 0)

    def _rebuild_scans(self) -> None:
        path = self.out / "scans.csv"
        lines = path.read_text(encoding="utf-8").splitlines(keepends=True)
        keep = [ln for ln in lines[1:] if ln.endswith("\n") and int(ln.split(",", 1)[0]) in self.done]
        tmp = path.with_suffix(".tmp")
        with open(tmp, "w", encoding="utf-8") as f:
            f.writelines([lines[0]] + keep)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)

    def close(self) -> None:
        """Release the run directory's lock (the operating system does it at exit anyway)."""
        if self._lock_fd is not None:
            release_run_dir(self._lock_fd)
            self._lock_fd = None

    def __enter__(self) -> "RunStore":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def notify(self, hook: str, *args) -> None:
        """Call ``hook`` on every observer (:class:`~.progress.CampaignObserver`)."""
        for observer in self.observers:
            getattr(observer, hook)(*args)

    def event(self, kind: str, **fields) -> None:
        """Journal one event (durable before returning), count it, tell the observers."""
        ev = {"event": kind, **fields}
        _append(self.out / "journal.jsonl", json.dumps(ev) + "\n")
        if kind != "run":
            self._account(ev)
        else:
            self.counts["runs"] += 1
        self.notify("event", kind, fields)

    def start_scan(self, scan_id: int) -> int:
        """Journal the start of an attempt at ``scan_id``; returns the attempt number (0-based)."""
        attempt = self.attempts[scan_id]
        self.event("scan_start", scan_id=scan_id, attempt=attempt)
        return attempt

    def append_sample(self, row: dict) -> None:
        """One sample (a dict over :data:`SAMPLE_COLUMNS`) to ``samples.csv``, durably."""
        _append(self.out / "samples.csv", _format(row, SAMPLE_COLUMNS))
        self.notify("sample", row)

    def finish_scan(self, scan_id: int, rows: list[dict]) -> None:
        """A complete scan to ``scans.csv``, then its ``scan_done`` event."""
        _append(self.out / "scans.csv", "".join(_format(r, SCAN_COLUMNS) for r in rows))
        self.event("scan_done", scan_id=scan_id, n_samples=len(rows))

    def write_summary(self, extra: dict) -> dict:
        """Write ``summary.json`` atomically; returns what was written."""
        summary = {"scans_done": len(self.done), "samples_written": self.counts["samples_written"],
                   "bad_frames": self.counts["bad_frames"], "bad_lines": self.counts["bad_lines"],
                   "late_samples": self.counts["late_samples"], "slow_scans": self.counts["slow_scans"],
                   "partial_lines_dropped": self.counts["partial_lines_dropped"],
                   "aborted_attempts": sum(self.attempts.values()) - len(self.done),
                   "runs": self.counts["runs"], **extra}
        tmp = self.out / "summary.json.tmp"
        write_json(tmp, summary)
        os.replace(tmp, self.out / "summary.json")
        return summary
