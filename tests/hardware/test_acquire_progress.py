"""Progress of a campaign: a live line on a terminal, a line per scan otherwise, none when
asked; observers see every sample (the hook a live decoder attaches to)."""
from __future__ import annotations

import io
import logging
from pathlib import Path

import pytest

from feeler.cli import main
from feeler.hardware.acquire.progress import CampaignObserver, Progress, format_duration
from feeler.hardware.acquire.session import DEFAULT_BOARD_NOTE as NOTE   # tiny plans' fast moves get it

TINY = Path(__file__).parent / "data" / "tiny-plan.toml"


class Clock:
    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now


def play(progress: Progress, clock: Clock, scans: int = 2, late: tuple = ()) -> None:
    """Four scans planned, one done by an earlier run; ``scans`` more of 4 samples, 10 s each."""
    progress.started(4, 1, 4)
    for i in range(1, 1 + scans):
        progress.event("scan_start", {"scan_id": i, "attempt": 0})
        for k in range(4):
            clock.now += 2.5
            progress.sample({"scan_id": i, "late": int((i, k) in late)})
        if i == 1:
            progress.event("bad_frame", {"scan_id": i, "sample": 3, "reason": "frozen"})
        progress.event("scan_done", {"scan_id": i, "n_samples": 4})
    progress.finished({"complete": False})


def test_a_line_per_finished_scan_off_a_terminal():
    out, clock = io.StringIO(), Clock()
    play(Progress(out, clock=clock), clock, late=((2, 1),))
    assert out.getvalue().splitlines() == [
        "feeler acquire: scan 1 done (2 of 4): 4 samples; so far 1 bad, 0 late; ETA 20s",
        "feeler acquire: scan 2 done (3 of 4): 4 samples; so far 1 bad, 1 late; ETA 10s"]


def test_live_line_on_a_terminal_redrawn_at_most_every_interval():
    out, clock = io.StringIO(), Clock()
    progress = Progress(out, live=True, interval_s=3.0, clock=clock)
    play(progress, clock, scans=1, late=((1, 2),))
    text = out.getvalue()
    frames = text.split("\r")[1:]
    assert text.endswith("\n") and len(frames) == 4          # samples at 2.5, 7.5 s; scan end; finish
    assert frames[0].startswith("scan 2 of 4 (id 1), sample 1 of 4; 1 samples, 0 bad, 0 late; ETA --")
    assert frames[-1].startswith("scan 3 of 4 (id 1), sample 4 of 4; 4 samples, 1 bad, 1 late; ETA 20s")


def test_a_warning_prints_on_its_own_line_under_a_live_line():
    out, clock = io.StringIO(), Clock()
    progress = Progress(out, live=True, clock=clock)
    progress.started(4, 0, 4)
    progress.sample({"late": 0})
    handler = logging.StreamHandler(out)
    handler.addFilter(progress.clear)
    logger = logging.getLogger("test.progress")
    logger.addHandler(handler)
    try:
        logger.warning("scan 0 sample 1: taken 0.040 s after its scheduled time")
    finally:
        logger.removeHandler(handler)
    clock.now += 1
    progress.sample({"late": 1})
    drawn, wiped, warning, redrawn = out.getvalue().split("\r")[1:]
    assert wiped.strip() == "" and warning == "scan 0 sample 1: taken 0.040 s after its scheduled time\n"
    assert redrawn.startswith("scan 1 of 4 (id -), sample 2 of 4; 2 samples, 0 bad, 1 late")


@pytest.mark.parametrize("seconds, text", [(0, "0s"), (59.4, "59s"), (61, "1m01s"), (3725, "1h02m")])
def test_format_duration(seconds, text):
    assert format_duration(seconds) == text


def test_cli_progress_forced_or_off_and_every_sample_reaches_an_observer(tmp_path, capsys):
    from feeler.hardware.acquire import acquire

    class Rows(CampaignObserver):
        def __init__(self):
            self.rows, self.events = [], []

        def sample(self, row):
            self.rows.append(row)

        def event(self, kind, fields):
            self.events.append(kind)

    plan = tmp_path / "one.toml"
    plan.write_text(TINY.read_text().replace("heights_mm = [0.0, 0.2]", "heights_mm = [0.0]")
                    .replace("origin_x_mm = [-20.0, -16.0]", "origin_x_mm = [-20.0]")
                    .replace("scans_per_plate = 2", "scans_per_plate = 1"))
    assert main(["acquire", "--emulate", "--plan", str(plan), "--out", str(tmp_path / "a"), "--progress"]) == 0
    err = capsys.readouterr().err
    assert "\rscan 1 of 1 (id 0), sample 4 of 4; 4 samples, 0 bad, " in err and err.endswith("\n")
    assert main(["acquire", "--emulate", "--plan", str(plan), "--out", str(tmp_path / "b"), "--no-progress"]) == 0
    assert [ln for ln in capsys.readouterr().err.splitlines() if not ln.startswith(NOTE)] == []
    watcher = Rows()
    summary = acquire(plan, tmp_path / "c", emulate=True, observers=(watcher,))
    assert [r["t_sched_s"] for r in watcher.rows] == pytest.approx([0.0, 0.1, 0.2, 0.3])
    assert watcher.events[0] == "scan_start" and watcher.events[-1] == "scan_done"
    assert summary["late_fraction"] == 0.25
    assert main(["acquire", "--emulate", "--plan", str(plan), "--out", str(tmp_path / "d"),
                 "--late-fraction", "0"]) == 2
    assert "argument --late-fraction=0.0: a fraction of the sample period > 0" in capsys.readouterr().err
    assert main(["acquire", "--emulate", "--plan", str(plan), "--out", str(tmp_path / "d"), "--home"]) == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("feeler:")]
    assert len(err) == 1 and "argument --home=True: a board with homing enabled ($22=1)" in err[0]
    assert main(["acquire", "--emulate", "--plan", str(plan), "--out", str(tmp_path / "d"), "--home",
                 "--unlock"]) == 2
    assert "argument --unlock=True: not together with --home" in capsys.readouterr().err
    assert not (tmp_path / "d").exists()


def test_live_eta_counts_down_through_a_scan():
    """The live line's ETA was (time so far / scans done) x scans left: it rose with every
    sample of a scan (an audit saw 3 s, then 6 s). It now falls by the time the scan has run."""
    out, clock = io.StringIO(), Clock()
    progress = Progress(out, live=True, interval_s=0.0, clock=clock)
    play(progress, clock, scans=1)                     # scan 1 took 10 s; 2 of 4 left
    assert progress.eta_s() == 20.0
    progress.event("scan_start", {"scan_id": 2, "attempt": 0})
    etas = []
    for _ in range(4):
        clock.now += 2.5
        progress.sample({"late": 0})
        etas.append(progress.eta_s())
    assert etas == [17.5, 15.0, 12.5, 10.0]
    clock.now += 30                                    # a slow scan: never below 0
    assert progress.eta_s() == 0.0
    assert out.getvalue().split("\r")[-1].startswith("scan 3 of 4 (id 2), sample 4 of 4; 8 samples, 1 bad, 0 late; ETA 10s")


def test_the_summary_line_counts_in_the_singular_and_names_the_journal(tmp_path):
    """acquire's last line said "1 scans where the stage moved slower than planned (see the
    log)" (an outside walk-through): no log was named (the event is in RUN/journal.jsonl, the
    warning went to stderr), and one scan was "1 scans", one bad line "1 bad lines"."""
    from feeler.commands.acquire import summary_line

    base = {"complete": True, "scans_done": 1, "scans_planned": 1, "samples_written": 41, "bad_frames": 0,
            "bad_lines": 1, "late_samples": 1, "partial_lines_dropped": 1, "slow_scans": 1}
    run = tmp_path / "run"
    assert summary_line(run, base) == (
        f"{run}: 1 of 1 scans (complete), 41 samples, 0 bad frames, 1 bad line, 1 late sample, 1 partial line "
        f"dropped; 1 scan where the stage moved slower than planned (the warning above, and slow_scan events in "
        f"{run / 'journal.jsonl'})")
    more = {**base, "scans_done": 3, "scans_planned": 4, "complete": False, "bad_lines": 2, "late_samples": 0,
            "partial_lines_dropped": 0, "slow_scans": 2}
    assert summary_line(run, more) == (
        f"{run}: 3 of 4 scans (incomplete), 41 samples, 0 bad frames, 2 bad lines, 0 late samples, 0 partial lines "
        f"dropped; 2 scans where the stage moved slower than planned (the warnings above, and slow_scan events in "
        f"{run / 'journal.jsonl'})")
    assert "slower" not in summary_line(run, {**base, "slow_scans": 0})
