"""The campaign runner: drive the stage and the camera together through a scan plan.

Per scan (:mod:`.plan` lists the moves): lift, go to the plate's start, lower, press, then
start the traverse and take a sample at every scheduled time ``t_k = k · sample_period_s``
after it began. A sample is the stage's status report (position) and a camera frame; the
frame's contact areas of the scanning element (:class:`feeler.hardware.camera.AreaExtractor`)
give the force by the area law and the displacement U = C F. Each sample is appended to
``samples.csv`` durably before the next is taken; the complete scan then goes to
``scans.csv`` and the journal (:mod:`.store`).

A bad frame (undecodable, wrong size, frozen tile, or rejected by the extractor) or a
bad status line is journalled, logged and counted; the sample is taken again from the
next frame or query (up to :data:`MAX_TRIES` times, then the campaign stops with an
error naming the camera or port). Damaged or lost replies that the stage driver itself
recovered from (``stage.recovered``: status queried again, move re-sent) are journalled
as bad lines too, each once, after the sample or scan in which they happened; so the
summary's ``bad_lines`` counts every damaged line.

Time base: ``t_s`` is when the sample's position was actually read — the midpoint of the
status query, whose round trip is ``status_rtt_s`` — from the moment the traverse was
commanded; so (t_s, x_mm) lie on the stage's motion whatever the scheduler did, and the
neuron core (exact on non-uniform times) uses them. ``t_sched_s`` is when the sample was
scheduled; a sample taken more than :data:`LATE_FRACTION` of a period after it is flagged
``late`` = 1, journalled as ``late_sample`` and counted in the summary, never relabelled;
the tolerance is :attr:`Setup.late_fraction` (``feeler acquire --late-fraction``).
``t_frame_s`` is when the frame arrived.

Observers of the store (:mod:`.progress`: the progress display, a live decoder) see the
campaign start, every sample as it is written, every event and the final summary.
"""
from __future__ import annotations

import logging
import time
from collections import Counter
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from feeler.errors import ArgumentError, DataFileError
from feeler.hardware.stage import ProtocolError, StageTimeout
from feeler.models.optics import Layout, OpticsParams

from .plan import ScanSpec, moves_of, sample_times_s, scans_of
from .store import RunStore

__all__ = ["MAX_TRIES", "LATE_FRACTION", "Setup", "run_campaign", "run_scan"]

log = logging.getLogger("feeler.acquire")
MAX_TRIES = 5
#: a sample read later than this fraction of the sample period after its schedule is late
LATE_FRACTION = 0.25


@dataclass(frozen=True)
class Setup:
    """What a campaign needs besides the devices.

    Attributes:
        plan: the loaded ``scan-plan`` scene.
        layout (Layout): the camera's view.
        c_mm_per_n (ndarray[3, 3]): C used to read U = C F (mm/N).
        optics (OpticsParams): the area law (rest area, gains).
        late_fraction (float): a sample read later than this fraction of the sample period
            after its schedule is late, > 0.
    """

    plan: object
    layout: Layout
    c_mm_per_n: np.ndarray
    optics: OpticsParams = OpticsParams()
    late_fraction: float = LATE_FRACTION

    def __post_init__(self):
        if not (isinstance(self.late_fraction, (int, float)) and 0 < self.late_fraction < float("inf")):
            raise ArgumentError("--late-fraction", self.late_fraction, "a fraction of the sample period > 0")

    @cached_property
    def pipeline(self):
        """The frame → displacement chain every sample is read with
        (:class:`feeler.hardware.camera.FramePipeline`)."""
        from feeler.hardware.camera import FramePipeline

        return FramePipeline(self.layout, self.plan.optics.element, self.c_mm_per_n, self.optics,
                             blur_sd_px=self.plan.optics.blur_sd_px)


def stopped_text(exc: BaseException) -> str:
    """Why a campaign stopped, in words for summary.json and the report (it read
    "KeyboardInterrupt: ", the exception's class name and an empty message)."""
    if isinstance(exc, KeyboardInterrupt):          # feeler turns SIGTERM into one ("signal 15")
        return f"interrupted ({str(exc).strip() or 'Ctrl-C'})"
    if isinstance(exc, SystemExit):
        return "stopped (the process was asked to exit)"
    text = str(exc).strip()
    return text if text else f"stopped by an error ({type(exc).__name__})"


def run_campaign(setup: Setup, stage, camera, store: RunStore, extra: dict) -> dict:
    """Run every scan not yet done; returns the final summary (also in ``summary.json``)."""
    extract = setup.pipeline
    scans = scans_of(setup.plan)
    extra = {**extra, "scans_planned": len(scans), "late_fraction": setup.late_fraction}
    seen: Counter = Counter()                    # driver recoveries already journalled
    store.notify("started", len(scans), len(store.done), len(sample_times_s(setup.plan)))
    _journal_recovered(stage, store, seen, None, None)   # replies recovered while opening the stage
    try:
        for scan in scans:
            if scan.scan_id in store.done:
                continue
            rows = run_scan(setup, stage, camera, extract, store, scan, seen=seen)
            store.finish_scan(scan.scan_id, rows)
            store.write_summary({**extra, "complete": False})
    except BaseException as exc:                 # the counts so far, and why the run stopped
        _journal_recovered(stage, store, seen, None, None)
        store.notify("finished", store.write_summary({**extra, "complete": False,
                                                      "stopped": stopped_text(exc)}))
        raise
    summary = store.write_summary({**extra, "complete": len(store.done) == len(scans)})
    store.notify("finished", summary)
    return summary


def run_scan(setup: Setup, stage, camera, extract, store: RunStore, scan: ScanSpec, *,
             seen: Counter | None = None) -> list[dict]:
    """One scan (one touch); returns its rows, each already in ``samples.csv``.

    ``seen`` (updated): the stage driver's recoveries already journalled (default: none).
    """
    seen = Counter() if seen is None else seen
    attempt = store.start_scan(scan.scan_id)
    moves = moves_of(setup.plan, scan)
    for move in moves[:4]:
        _move(stage, move)
    camera.start_scan(scan.scan_id)
    rows = []
    try:
        _move(stage, moves[4], wait=False)
        t0 = time.monotonic()
        late_s = setup.late_fraction * float(setup.plan.scan.sample_period_s)
        for k, t_k in enumerate(sample_times_s(setup.plan)):
            time.sleep(max(0.0, t0 + t_k - time.monotonic()))
            row = _sample(setup, stage, camera, extract, store, scan, k, seen)
            t_read = row["t_s"] - t0
            late = t_read - float(t_k) > late_s
            row.update(t_s=t_read, t_sched_s=float(t_k), late=int(late), t_frame_s=row["t_frame_s"] - t0,
                       attempt=attempt)
            store.append_sample(row)
            if late:
                log.warning("scan %d sample %d: taken %.3f s after its scheduled time %.3f s",
                            scan.scan_id, k, t_read - t_k, t_k)
                store.event("late_sample", scan_id=scan.scan_id, sample=k, t_s=t_read, t_sched_s=float(t_k))
            rows.append(row)
        stage.wait_idle()
    finally:
        camera.end_scan()
    plan = setup.plan.scan
    short = slow_scan(rows, float(plan.speed_mm_s), float(stage.limits.accel_mm_s2[0]), float(plan.traverse_mm))
    if short is not None:
        at, expected = short
        log.warning("scan %d: at its last sample the stage was %.3g mm along its traverse, %.0f %% of the %.3g mm "
                    "that %.3g mm/s puts it at: a stage slower than commanded, so the samples' positions are not "
                    "the plan's (the step may not have been reached); the scan is kept",
                    scan.scan_id, at, 100 * at / expected, expected, float(plan.speed_mm_s))
        store.event("slow_scan", scan_id=scan.scan_id, along_mm=at, expected_mm=expected)
    _move(stage, moves[5])
    _journal_recovered(stage, store, seen, scan.scan_id, None)
    return rows


#: a scan whose stage is less than this share of the way the plan's speed puts it at its last
#: sample (accelerating at the board's $120, at most the traverse) is reported: grbl-sim moved
#: at 0.8-1.0 mm/s under a 2 mm/s plan, covered 1.6-2.0 of 4 mm, never reached the step at
#: 2 mm, and the run said "complete" (an outside test)
SLOW_SCAN_SHARE = 0.8


def slow_scan(rows: list[dict], speed_mm_s: float, accel_mm_s2: float, traverse_mm: float) -> tuple[float, float] | None:
    """(mm along, mm expected) of a scan's last sample when the stage was less than
    :data:`SLOW_SCAN_SHARE` of the way that ``speed_mm_s`` puts it at its read time (from
    rest at ``accel_mm_s2``, at most ``traverse_mm``), else None. The read time, not the
    schedule: a sample read late on a busy host finds the stage further, not behind."""
    if not rows or not speed_mm_s > 0:
        return None
    t = max(float(rows[-1]["t_s"]), 0.0)
    ramp_s = speed_mm_s / accel_mm_s2 if accel_mm_s2 > 0 else 0.0
    along = 0.5 * accel_mm_s2 * t * t if t < ramp_s else speed_mm_s * (t - 0.5 * ramp_s)
    expected = min(along, traverse_mm)
    at = abs(float(rows[-1]["x_mm"]))
    return (at, expected) if expected > 0 and at < SLOW_SCAN_SHARE * expected else None


def _move(stage, move, wait: bool = True) -> None:
    _, target, feed, axes = move
    stage.move_to(**{f"{a}_mm": v for a, v in zip("xyz", target) if a in axes}, feed_mm_min=feed)
    if wait:
        stage.wait_idle()


def _sample(setup: Setup, stage, camera, extract, store: RunStore, scan: ScanSpec, k: int,
            seen: Counter) -> dict:
    problem = "no attempt"
    for _ in range(MAX_TRIES):
        before = time.monotonic()
        pos = _status(stage, store, scan.scan_id, k, seen).mpos_mm
        after = time.monotonic()
        grab = camera.grab(pos, k)
        problem = grab.problem
        if problem is None:
            areas, problem = extract(grab.frame)
        if problem is None:
            break
        log.warning("%s: scan %d sample %d: bad frame: %s", camera.name, scan.scan_id, k, problem)
        store.event("bad_frame", scan_id=scan.scan_id, sample=k, reason=problem)
    else:
        raise DataFileError(camera.name, f"{MAX_TRIES} bad frames in a row at scan {scan.scan_id} "
                            f"sample {k}; last: {problem}")
    reading = setup.pipeline.reading(areas)
    a, f, u = reading.areas_px2, reading.force_n, reading.u_mm
    plan = setup.plan
    return {"scan_id": scan.scan_id, "plate": scan.plate, "step_mm": scan.step_mm,
            "speed_mm_s": float(plan.scan.speed_mm_s), "x_mm": float(pos[0] - scan.origin_x_mm),
            "ux_mm": float(u[0]), "uy_mm": float(u[1]), "uz_mm": float(u[2]), "repeat": scan.repeat,
            "t_s": 0.5 * (before + after), "status_rtt_s": after - before,
            "t_frame_s": grab.t_s, "stage_x_mm": float(pos[0]), "stage_y_mm": float(pos[1]),
            "stage_z_mm": float(pos[2]), **{f"area{i}_px2": float(v) for i, v in enumerate(a)},
            "fx_n": float(f[0]), "fy_n": float(f[1]), "fz_n": float(f[2])}


def _status(stage, store: RunStore, scan_id: int, k: int, seen: Counter | None = None):
    """The stage's status; a lost or damaged report is journalled as a bad line and retried
    after a resync, :data:`MAX_TRIES` tries in all (as are those the driver recovered from
    since ``seen``, see :func:`_journal_recovered`). A resync that fails is a try too: it
    ran in the except clause, so one timing out ended the run at the second bad line."""
    for tries in range(1, MAX_TRIES + 1):
        try:
            if tries > 1:
                stage.protocol.resync()
            status = stage.status()
            _journal_recovered(stage, store, Counter() if seen is None else seen, scan_id, k)
            return status
        except (ProtocolError, StageTimeout) as exc:
            if (isinstance(exc, ProtocolError) and exc.code is not None) or tries == MAX_TRIES:
                raise
            log.warning("%s: scan %d sample %d: bad status line: %s", stage.port, scan_id, k, exc)
            store.event("bad_line", scan_id=scan_id, sample=k, reason=str(exc))
    raise AssertionError("unreachable")


def _journal_recovered(stage, store: RunStore, seen: Counter, scan_id: int | None, k: int | None) -> None:
    """Journal one ``bad_line`` per reply the stage driver recovered from since ``seen``
    (a stage without a ``recovered`` count, e.g. a test fake, has none); updates ``seen``."""
    now = getattr(stage, "recovered", None) or {}
    for key in sorted(now):
        for _ in range(now[key] - seen[key]):
            store.event("bad_line", scan_id=scan_id, sample=k, reason=f"recovered by the driver: {key}")
        seen[key] = now[key]
