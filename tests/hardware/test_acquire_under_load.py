"""A campaign with both cores busy records the truth: every (t, x) on the commanded motion.

The test starts two busy-loop processes itself (and stops them by PID), runs an emulated
campaign, and checks each scan's samples against the traverse the plan commanded — speed
from the plan, acceleration from the emulated board's ``$120`` — with only what the driver
guarantees as tolerance: the status query's round trip and the position report's
resolution. Samples the scheduler delayed are flagged late, never moved onto the schedule.
"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
from motion_profile import Trapezoid, start_bounds

DATA = Path(__file__).parent / "data"
TINY = DATA / "tiny-plan.toml"


def check_on_the_commanded_profile(run: Path, plan_path: Path = TINY) -> pd.DataFrame:
    """Assert that each scan's (t_s, x_mm) lie on one commanded traverse; returns the rows."""
    from feeler.hardware.acquire import load_plan
    from feeler.hardware.acquire.emulated import FAST_STAGE

    plan = load_plan(plan_path)
    rows = pd.read_csv(run / "scans.csv")
    accel = FAST_STAGE.table()[120]
    q = 0.5 / FAST_STAGE.table()[100] + 0.0005            # half a step and the report's rounding
    profile = Trapezoid(plan.scan.traverse_mm, plan.scan.speed_mm_s, accel)
    for scan_id, r in rows.groupby("scan_id"):
        lo, hi = start_bounds(profile, r.t_s, r.x_mm, r.status_rtt_s, q)
        assert lo <= hi, f"scan {scan_id}: no one traverse explains t={list(r.t_s)}, x={list(r.x_mm)}"
        assert np.all(np.diff(r.t_s) > 0) and np.all(np.diff(r.x_mm) >= -q)
    period = plan.scan.sample_period_s
    late = rows.t_s - rows.t_sched_s > 0.25 * period
    np.testing.assert_array_equal(rows.late.to_numpy(), late.astype(int).to_numpy())
    return rows


def test_campaign_with_both_cores_busy_records_the_truth(tmp_path):
    from feeler.hardware.acquire import acquire

    loops = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(2)]
    try:
        summary = acquire(TINY, tmp_path / "run", emulate=True)
    finally:
        for loop in loops:                         # by PID: these two and nothing else
            loop.kill()
        for loop in loops:
            loop.wait()
    assert summary["complete"] and summary["samples_written"] == 16
    rows = check_on_the_commanded_profile(tmp_path / "run")
    assert summary["late_samples"] == int(rows.late.sum())


def test_the_profile_check_catches_a_sample_relabelled_with_its_schedule():
    """Samples on an exact traverse pass; the same samples with one time stamp replaced by
    the schedule it missed by 8 ms (what the campaign once recorded) fail."""
    profile = Trapezoid(3.0, 10.0, 2000.0)
    t0, t_true = 0.003, np.array([0.0, 0.1, 0.208, 0.3])                 # sample 2 read 8 ms late
    x = np.round([profile.position_at(t - t0) for t in t_true], 3)           # reported to 1 µm
    rtt = np.full(4, 0.002)
    lo, hi = start_bounds(profile, t_true, x, rtt, 0.001)
    assert lo <= t0 <= hi
    relabelled = t_true.copy()
    relabelled[2] = 0.2
    lo, hi = start_bounds(profile, relabelled, x, rtt, 0.001)
    assert lo > hi
