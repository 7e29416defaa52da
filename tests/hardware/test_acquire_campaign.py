"""Campaigns against the Grbl emulator in a separate process over a real pty.

One uninterrupted reference run (module fixture) is compared with a run killed with
``kill -9`` mid-scan and resumed, and its recorded video is replayed as a camera.
"""
from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from feeler.cli import main
from feeler.datasets import read_scans
from feeler.errors import CalibrationFailed
from feeler.hardware.acquire.session import DEFAULT_BOARD_NOTE as NOTE   # tiny plans' fast moves get it

DATA = Path(__file__).parent / "data"
TINY = DATA / "tiny-plan.toml"
AREAS = [f"area{i}_px2" for i in range(4)]
EXACT = ["scan_id", "plate", "step_mm", "speed_mm_s", "t_sched_s", "repeat"]


def one_scan_plan(tmp_path: Path) -> Path:
    path = tmp_path / "one.toml"
    path.write_text(TINY.read_text().replace("heights_mm = [0.0, 0.2]", "heights_mm = [0.0]")
                    .replace("origin_x_mm = [-20.0, -16.0]", "origin_x_mm = [-20.0]")
                    .replace("scans_per_plate = 2", "scans_per_plate = 1"))
    return path


def table(run: Path, name: str = "scans.csv") -> pd.DataFrame:
    return pd.read_csv(run / name)


def rerendered_areas(run: Path, plan_path: Path) -> np.ndarray:
    """Areas of every row re-rendered from the recorded stage position and the scan's seed."""
    from feeler.hardware.acquire import load_plan
    from feeler.hardware.acquire.cameras import sample_rng
    from feeler.hardware.acquire.world import VirtualWorld
    from feeler.hardware.camera import AreaExtractor

    plan = load_plan(plan_path)
    world = VirtualWorld.of_plan(plan, plan_path)
    extract = AreaExtractor(world.layout, blur_sd_px=plan.optics.blur_sd_px)
    out = []
    for r in table(run).itertuples():
        k = int(round(r.t_sched_s / plan.scan.sample_period_s))
        frame = world.render(int(r.scan_id), (r.stage_x_mm, r.stage_y_mm, r.stage_z_mm),
                             sample_rng(plan.scene.seed, int(r.scan_id), k))
        out.append(extract(frame)[0][plan.optics.element])
    return np.array(out)


def check_against_the_virtual_world(run: Path) -> None:
    """Exact re-rendering, and U within the reader's accuracy of the true U."""
    from feeler.hardware.acquire import load_plan
    from feeler.hardware.acquire.world import VirtualWorld

    rows = table(run)
    np.testing.assert_array_equal(rerendered_areas(run, TINY), rows[AREAS].to_numpy())
    world = VirtualWorld.of_plan(load_plan(TINY), TINY)
    truth = np.array([world.truth_mm(int(r.scan_id), (r.stage_x_mm, r.stage_y_mm, r.stage_z_mm))
                      for r in rows.itertuples()])
    np.testing.assert_allclose(rows[["ux_mm", "uy_mm", "uz_mm"]].to_numpy(), truth, atol=0.006)


def check_time_base(run: Path, summary: dict) -> None:
    """Every recorded (t_s, x_mm) lies on the commanded traverse, whatever the scheduler did.

    Per scan one trapezoidal traverse (the plan's speed, the emulated board's acceleration)
    from an unobserved start must explain every sample within its status query's round
    trip and the position report's resolution (``check_on_the_commanded_profile``);
    samples read at rest before or after it count too, so a scheduler that slept through
    the whole traverse fails nothing it should not. Scheduled times are exactly
    k · period, and a sample is flagged late exactly when it was read over a quarter
    period after its schedule.
    """
    from test_acquire_under_load import check_on_the_commanded_profile

    period = load_plan_scan().sample_period_s
    rows = check_on_the_commanded_profile(run, TINY)
    for _, r in rows.groupby("scan_id"):
        np.testing.assert_allclose(r.t_sched_s, np.arange(len(r)) * period, rtol=0, atol=1e-12)
        assert np.all(r.status_rtt_s > 0)
    late = rows.t_s - rows.t_sched_s > 0.25 * period
    np.testing.assert_array_equal(rows.late.to_numpy(), late.astype(int).to_numpy())
    assert summary["late_samples"] >= int(late.sum())          # killed attempts may add more
    assert summary["slow_scans"] == 0                           # on the commanded traverse: none slower


def load_plan_scan():
    from feeler.hardware.acquire import load_plan

    return load_plan(TINY).scan


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    from feeler.hardware.acquire import acquire

    run = tmp_path_factory.mktemp("acq") / "reference"
    summary = acquire(TINY, run, emulate=True)
    return run, summary


def test_emulated_campaign_is_a_neuron_dataset(reference):
    from feeler.calib.neuron import data_from_scans
    from feeler.commands._calibrate_neuron import locate_scans

    run, summary = reference
    assert summary["complete"] and (summary["scans_done"], summary["samples_written"]) == (4, 16)
    assert (summary["bad_frames"], summary["bad_lines"], summary["aborted_attempts"]) == (0, 0, 0)
    scans = read_scans(run)
    np.testing.assert_array_equal(scans.step_mm, [0.0, 0.0, 0.2, 0.2])
    check_time_base(run, summary)
    csv, length_mm, kernel = locate_scans(run, None)                  # what `calibrate neuron RUN` does
    data = data_from_scans(read_scans(csv), length_mm=length_mm, kernel=kernel)
    assert (length_mm, kernel, data.strain.shape) == (3.0, "boxcar", (4, 4))
    assert table(run, "samples.csv").drop(columns="attempt").equals(table(run))
    check_against_the_virtual_world(run)
    assert sorted(p.name for p in (run / "video").iterdir()) == [f"scan_000{i}.avi" for i in range(4)]


def m1_fit_dir(tmp_path: Path, draws: int) -> tuple[Path, np.ndarray]:
    """An M1 fit directory (exact backend on the shipped calibration campaign) and its mean C."""
    from feeler.calib.matrix import MatrixPrior, fit_matrix, read_calibration_csv
    from feeler.simulate import run_simulation

    scene = Path(__file__).parents[2] / "datasets-synthetic" / "sensor-calibration.toml"
    run = run_simulation(scene, tmp_path / "cal", force=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")                     # the failed fit is meant to fail
        result = fit_matrix(read_calibration_csv(run / "calibration.csv"),
                            MatrixPrior(c0_mm_per_n=((0.25, 0, 0), (0, 0.2, 0), (0, 0, 0.25))),
                            rng=np.random.default_rng(0), chains=2, draws=draws)
    out = result.save(tmp_path / f"fit{draws}")
    return out, result.posterior["posterior"]["C"].mean(("chain", "draw")).values


def test_replay_with_a_frozen_frame_and_a_calibrated_c(reference, tmp_path):
    """The recorded video with frame 1 repeated: one bad frame counted and skipped, the
    same areas as the virtual camera's, and U read through the M1 posterior mean."""
    from feeler.hardware.acquire import acquire
    from feeler.hardware.camera import write_video
    from feeler.hardware.camera.source import FrameReader

    run, _ = reference
    frames = np.array([f for _, f in FrameReader(run / "video" / "scan_0000.avi")])
    video = write_video(frames[[0, 1, 1, 2, 3]], tmp_path / "frozen.avi")
    plan = one_scan_plan(tmp_path)
    replay = tmp_path / "replay"
    failed, _ = m1_fit_dir(tmp_path, 100)                  # too few draws: fails its diagnostics
    with pytest.raises(CalibrationFailed, match="accept-failed"):
        acquire(plan, replay, emulate=True, camera_src=str(video), calibration=failed)
    assert not replay.exists()
    from feeler.hardware.acquire.session import c_from_calibration
    assert c_from_calibration(failed, accept_failed=True)[1] == f"posterior mean of {failed}"   # acquire --accept-failed
    fit, c_mean = m1_fit_dir(tmp_path, 1000)
    summary = acquire(plan, replay, emulate=True, camera_src=str(video), calibration=fit)
    assert summary["complete"] and summary["bad_frames"] == 1 and summary["camera"] == str(video)
    assert summary["c_source"] == f"posterior mean of {fit}"
    got = table(replay)
    np.testing.assert_array_equal(got[AREAS].to_numpy(), table(run)[AREAS].to_numpy()[:4])
    f = got[["fx_n", "fy_n", "fz_n"]].to_numpy()
    np.testing.assert_allclose(got[["ux_mm", "uy_mm", "uz_mm"]].to_numpy(), f @ c_mean.T, rtol=1e-12, atol=1e-15)
    assert '"reason": "tile at column' in (replay / "journal.jsonl").read_text()


def test_garbled_and_truncated_status_replies_are_never_used(tmp_path, capsys):
    """Faults in the emulator: the driver re-queries, the campaign completes, and every
    recorded position is one the virtual camera really rendered (exact re-rendering)."""
    plan = one_scan_plan(tmp_path)
    run = tmp_path / "faulty"
    faults = ["garble:reply=status,nth=6", "truncate:reply=status,nth=12"]     # (a drop costs a 2 s timeout)
    argv = ["acquire", "--emulate", "--plan", str(plan), "--out", str(run)]
    assert main(argv + [a for f in faults for a in ("--fault", f)]) == 0
    assert "1 of 1 scans (complete)" in capsys.readouterr().out
    np.testing.assert_array_equal(rerendered_areas(run, plan), table(run)[AREAS].to_numpy())
    assert main(["acquire", "--stage", "x", "--camera", "0", "--fault", faults[0], "--plan", str(plan),
                 "--out", str(tmp_path / "no")]) == 2
    assert "--fault" in capsys.readouterr().err


def test_corrupt_video_mid_run_is_one_line_and_keeps_what_was_written(reference, tmp_path, capsys):
    run, _ = reference
    data = (run / "video" / "scan_0000.avi").read_bytes()
    bad = tmp_path / "corrupt.avi"
    half = len(data) // 2
    bad.write_bytes(data[:half] + bytes(3000) + data[half + 3000:])
    out = tmp_path / "run"
    code = main(["acquire", "--emulate", "--camera", str(bad), "--plan", str(one_scan_plan(tmp_path)),
                 "--out", str(out)])
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("feeler:") and not ln.startswith(NOTE)]
    assert code == 2 and len(err) == 1 and str(bad) in err[0] and "truncated or corrupt" in err[0]
    samples = table(out, "samples.csv")
    assert len(samples) >= 1 and list(samples["t_sched_s"]) == [0.1 * k for k in range(len(samples))]
    journal = (out / "journal.jsonl").read_text()
    assert '"event": "bad_frame"' in journal and "identical to the previous frame" in journal


def test_plan_beyond_the_soft_limits_is_refused_before_writing(tmp_path, capsys):
    plan = tmp_path / "far.toml"
    plan.write_text(TINY.read_text().replace("origin_x_mm = [-20.0, -16.0]", "origin_x_mm = [-20.0, -2.0]"))
    code = main(["acquire", "--emulate", "--plan", str(plan), "--out", str(tmp_path / "run")])
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("feeler:") and not ln.startswith(NOTE)]
    assert code == 2 and len(err) == 1
    assert "scan.traverse_mm: scan 2 moves x to 1 mm, beyond the soft limits [-200, 0] mm of the emulated " \
        "stage (Grbl's [-$130..$132, 0])" in err[0]                # not the emulator's /dev/pts path
    assert not (tmp_path / "run").exists()


def _children(pid: int) -> list[int]:
    path = Path(f"/proc/{pid}/task/{pid}/children")
    return [int(p) for p in path.read_text().split()] if path.exists() else []


def _alive(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().split()[2] != "Z"
    except FileNotFoundError:
        return False


def test_kill_9_mid_scan_then_resume_completes_like_an_uninterrupted_run(reference, tmp_path, capsys):
    ref, _ = reference
    run = tmp_path / "killed"
    cmd = [sys.executable, "-m", "feeler", "acquire", "--emulate", "--plan", str(TINY), "--out", str(run)]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    samples = run / "samples.csv"
    deadline = time.monotonic() + 60
    while not (samples.exists() and samples.read_text().count("\n") >= 1 + 6):   # scan 1, 2 of 4 samples
        assert proc.poll() is None and time.monotonic() < deadline, proc.stderr.read() if proc.poll() else ""
        time.sleep(0.005)
    children = _children(proc.pid)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    proc.stderr.close()
    deadline = time.monotonic() + 10
    while any(_alive(c) for c in children) and time.monotonic() < deadline:
        time.sleep(0.05)
    leftover = [c for c in children if _alive(c)]
    for c in leftover:
        os.kill(c, signal.SIGKILL)
    assert children and not leftover, "the emulator outlived its killed campaign"

    # readable right away: complete scans in scans.csv, every sample up to the one in flight
    assert list(read_scans(run).scan_id) == [0]
    lines = samples.read_text().splitlines()
    rows = [ln.split(",") for ln in lines[1:] if ln.count(",") == len(lines[0].split(",")) - 1]
    assert len(lines) - 1 - len(rows) <= 1                                       # at most one cut line
    sched = lines[0].split(",").index("t_sched_s")
    scan1 = [r for r in rows if r[0] == "1"]
    assert [float(r[sched]) for r in scan1] == [0.1 * k for k in range(len(scan1))] and len(scan1) >= 2

    assert main(["acquire", "--emulate", "--plan", str(TINY), "--out", str(run), "--resume"]) == 0
    assert "4 of 4 scans (complete)" in capsys.readouterr().out
    import json
    summary = json.loads((run / "summary.json").read_text())
    assert (summary["runs"], summary["aborted_attempts"], summary["scans_done"]) == (2, 1, 4)
    assert summary["partial_lines_dropped"] <= 1 and summary["samples_written"] == 16
    got, want = table(run), table(ref)
    pd.testing.assert_frame_equal(got[EXACT], want[EXACT])
    check_time_base(run, summary)
    check_against_the_virtual_world(run)
    assert set(table(run, "samples.csv").query("scan_id == 1")["attempt"]) == {0, 1}


def test_sigterm_stops_the_run_cleanly_and_says_where(tmp_path):
    run = tmp_path / "stopped"
    cmd = [sys.executable, "-m", "feeler", "acquire", "--emulate", "--plan", str(TINY), "--out", str(run)]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 60
    while not ((run / "samples.csv").exists() and (run / "samples.csv").read_text().count("\n") >= 3):
        assert proc.poll() is None and time.monotonic() < deadline
        time.sleep(0.005)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=30)
    import json
    summary = json.loads((run / "summary.json").read_text())
    assert proc.returncode == 130 and "feeler: interrupted" in err
    assert summary["complete"] is False and summary["stopped"] == "interrupted (signal 15)"   # was "KeyboardInterrupt: ..."


def test_ctrl_c_at_a_terminal_is_one_line_not_the_emulators_traceback(tmp_path):
    """A terminal's Ctrl-C signals the whole process group: the emulator child printed a
    KeyboardInterrupt traceback (pty_server.py, select) under 'feeler: interrupted'."""
    run = tmp_path / "stopped"
    cmd = [sys.executable, "-m", "feeler", "acquire", "--emulate", "--plan", str(TINY), "--out", str(run),
           "--no-progress"]
    # its own group, as a shell's job is, with Ctrl-C's default disposition as a terminal's
    # foreground job has it: a suite run in the background of a script (`make test &`) ignores
    # SIGINT, its children inherit that, and the run went on to the end (exit 0)
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            start_new_session=True, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.monotonic() + 60
    while not ((run / "samples.csv").exists() and (run / "samples.csv").read_text().count("\n") >= 3):
        assert proc.poll() is None and time.monotonic() < deadline
        time.sleep(0.005)
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 130
    # the tiny plan's 6000 mm/min moves get a note that a board at Grbl's defaults would refuse them; on a
    # host busier than its cores a sample can be taken late, which is warned about (seen once, at 3x load)
    late = re.compile(r"feeler: warning: scan \d+ sample \d+: taken [0-9.]+ s after its scheduled time")
    assert [ln for ln in err.strip().splitlines() if not ln.startswith(NOTE) and not late.match(ln)] == [
        "feeler: interrupted (run the same command with --resume to continue)"]


def test_missing_camera_on_resume_changes_nothing(reference, tmp_path, capfd):
    run, _ = reference
    before = {p.name: p.read_bytes() for p in run.iterdir() if p.is_file()}
    code = main(["acquire", "--emulate", "--camera", "57", "--plan", str(TINY), "--out", str(run), "--resume"])
    lines = capfd.readouterr().err.splitlines()       # file descriptors: OpenCV writes its log there itself
    err = [ln for ln in lines if ln.startswith("feeler:") and not ln.startswith(NOTE)]
    assert code == 2 and err == ["feeler: error: camera 57: no camera device at this index"]
    assert not [ln for ln in lines if "WARN" in ln or "VIDEOIO" in ln], lines     # OpenCV's own log line
    assert {p.name: p.read_bytes() for p in run.iterdir() if p.is_file()} == before


def test_two_uninterrupted_runs_agree_to_the_emulators_noise_model(reference, tmp_path):
    """Two runs of one plan and seed read the stage at slightly different instants (the
    scheduler's, and the emulator's, timing), so their positions differ by up to a few
    hundredths of a millimetre; everything else follows from the motion and the seed:

    - the schedule and labels are identical, and each run's (t, x) lie on the commanded
      traverse (``check_on_the_commanded_profile``): their position differences are their
      time differences;
    - each sample's noise is drawn for that sample alone (same seed, scan, sample), so
      U_a − U_b is the true U's change between the two positions, up to the camera's own
      noise: within 4·√2 standard deviations of U, the deviation measured by rendering the
      sensor afresh 12 times (its upper 99.9 % confidence bound, chi-square with 11 dof).
    """
    from scipy.stats import chi2

    from feeler.hardware.acquire import acquire, load_plan
    from feeler.hardware.acquire.world import VirtualWorld
    from feeler.hardware.camera import AreaExtractor
    from feeler.models.optics import displacement_from_force, force_from_areas
    from test_acquire_under_load import check_on_the_commanded_profile

    run_a, _ = reference
    run_b = tmp_path / "again"
    acquire(TINY, run_b, emulate=True)
    a, b = table(run_a), table(run_b)
    pd.testing.assert_frame_equal(a[EXACT], b[EXACT])
    check_on_the_commanded_profile(run_a)
    check_on_the_commanded_profile(run_b)
    plan = load_plan(TINY)
    world = VirtualWorld.of_plan(plan, TINY)
    stage = ["stage_x_mm", "stage_y_mm", "stage_z_mm"]
    truth = [np.array([world.truth_mm(int(s), p) for s, p in zip(t.scan_id, t[stage].to_numpy())]) for t in (a, b)]
    extract = AreaExtractor(world.layout, blur_sd_px=plan.optics.blur_sd_px)
    edge = (plan.plates.origin_x_mm[1] + plan.virtual.step_position_mm, plan.plates.y_mm,
            plan.plates.surface_z_mm - plan.scan.press_mm)                  # where U changes fastest
    u = [displacement_from_force(force_from_areas(extract(world.render(2, edge, np.random.default_rng(i)))[0][5],
                                                  world.optics), world.optics.c_matrix) for i in range(12)]
    sd = np.std(u, axis=0, ddof=1) * np.sqrt(11 / chi2.ppf(0.001, 11))
    du = a[["ux_mm", "uy_mm", "uz_mm"]].to_numpy() - b[["ux_mm", "uy_mm", "uz_mm"]].to_numpy()
    residual = np.abs(du - (truth[0] - truth[1]))
    assert np.all(residual <= 4 * np.sqrt(2) * sd + 1e-12)


def test_the_runs_own_copy_of_its_plan_resumes_with_its_layout(tmp_path, capsys):
    """`--resume` with another plan says to pass RUN/scene.toml, the run's copy of its plan;
    that copy named its layout by a path relative to the plan ('../layouts/...'), which the
    run directory does not reach: 'no such layout file' (an outside audit). The run keeps a
    copy of the layout, and its plan copy reads it."""
    layouts, plans = tmp_path / "layouts", tmp_path / "plans"
    layouts.mkdir()
    plans.mkdir()
    shipped = Path(__file__).resolve().parents[2] / "datasets-synthetic" / "layouts" / "sensor-16.toml"
    (layouts / "sensor-16.toml").write_bytes(shipped.read_bytes())
    plan = plans / "plan.toml"
    plan.write_text(one_scan_plan(tmp_path).read_text().replace("[optics]\n", '[optics]\nlayout = "../layouts/sensor-16.toml"\n'))
    run = tmp_path / "runs" / "run"                 # RUN/../layouts does not exist
    assert main(["acquire", "--emulate", "--plan", str(plan), "--out", str(run), "--no-progress"]) == 0
    assert (run / "layout.toml").read_bytes() == shipped.read_bytes()
    capsys.readouterr()
    assert main(["acquire", "--emulate", "--plan", str(run / "scene.toml"), "--out", str(run), "--resume",
                 "--no-progress"]) == 0, capsys.readouterr().err
    assert "no such layout file" not in capsys.readouterr().err


def test_a_dry_run_says_when_a_board_at_grbls_defaults_would_refuse_the_plan(tmp_path, capsys):
    """--emulate's stage allows 6000 mm/min per axis: a plan with a 600 mm/min traverse ran
    to the end in silence, though a board at Grbl's default $110 = 500 mm/min refuses it
    (an outside audit). The shipped plan, within the defaults, gets no note."""
    plan = tmp_path / "fast.toml"
    plan.write_text(one_scan_plan(tmp_path).read_text().replace("move_feed_mm_min = 6000.0", "move_feed_mm_min = 500.0")
                    .replace("press_feed_mm_min = 3000.0", "press_feed_mm_min = 500.0"))
    assert "speed_mm_s = 10.0" in plan.read_text()
    assert main(["acquire", "--emulate", "--plan", str(plan), "--out", str(tmp_path / "run"), "--no-progress"]) == 0
    (note,) = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith(NOTE)]
    assert note.endswith("would refuse it: scan.speed_mm_s: 10 mm/s (600 mm/min) is above the ceiling of 500 mm/min "
                         "of a board at Grbl's default settings for this move ($110, the x axis' maximum rate, is 500 "
                         "mm/min): lower scan.speed_mm_s or raise $110")
    from feeler.hardware.acquire import load_plan
    from feeler.hardware.acquire.emulated import emulated_stage
    from feeler.hardware.acquire.session import _note_a_default_board

    shipped = Path(__file__).resolve().parents[2] / "datasets-synthetic" / "plans" / "four-plates-plan.toml"
    _note_a_default_board(load_plan(shipped), shipped, emulated_stage(load_plan(shipped)).start_mm)
    assert capsys.readouterr().err == ""


def test_a_video_shorter_than_the_plan_is_refused_before_the_stage_moves(reference, tmp_path, capsys):
    """One scan's recording replayed under the four-scan plan ran its first scan, then
    stopped with 'the video ended (truncated or corrupt) before the plan did' (an outside
    audit): the frames it states are counted first, and nothing is written."""
    run, _ = reference
    out = tmp_path / "replay"
    video = run / "video" / "scan_0000.avi"
    assert main(["acquire", "--emulate", "--camera", str(video), "--plan", str(TINY), "--out", str(out)]) == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("feeler:") and not ln.startswith(NOTE)]
    assert err == [f"feeler: error: {video}: holds 4 frames; the plan (4 scans of 4 samples) needs at least 16, one "
                   "per sample (a run's video/scan_NNNN.avi replays its one scan: use a plan of that scan, or an "
                   "image sequence of the whole run)"]
    assert not out.exists()


def test_a_video_cut_short_that_states_its_whole_count_is_refused_before_the_stage_moves(reference, tmp_path,
                                                                                          capsys):
    """A recording cut in half keeps its container's frame count: the stage moved and frames
    were taken for 11.9 s before 'the video ended' (an outside audit). Its frames are counted
    by grabbing them before anything moves; nothing is written. The whole recording replays."""
    run, _ = reference
    whole = run / "video" / "scan_0000.avi"
    plan = one_scan_plan(tmp_path)
    cut = tmp_path / "cut.avi"
    data = whole.read_bytes()
    cut.write_bytes(data[: len(data) // 2])
    out = tmp_path / "replay"
    assert main(["acquire", "--emulate", "--camera", str(cut), "--plan", str(plan), "--out", str(out)]) == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("feeler:") and not ln.startswith(NOTE)]
    assert len(err) == 1 and err[0].startswith(f"feeler: error: {cut}: holds ") and "readable frames" in err[0], err
    assert "(the file is cut short or corrupt)" in err[0]
    assert not out.exists()
    assert main(["acquire", "--emulate", "--camera", str(whole), "--plan", str(plan), "--out",
                 str(tmp_path / "whole"), "--no-progress"]) == 0


def test_a_bad_frame_is_a_feeler_warning_line_not_a_log_record(reference, tmp_path):
    """Per-frame warnings printed as 'WARNING feeler.acquire: ...', a log's format, among the
    CLI's 'feeler: error: ...' lines (an outside audit); -v still names the logger."""
    from feeler.hardware.camera import write_video
    from feeler.hardware.camera.source import FrameReader

    run, _ = reference
    frames = np.array([f for _, f in FrameReader(run / "video" / "scan_0000.avi")])
    video = write_video(frames[[0, 1, 1, 2, 3]], tmp_path / "frozen.avi")
    plan = one_scan_plan(tmp_path)
    for verbose, out in ((), "quiet"), (("-v",), "loud"):
        cmd = [sys.executable, "-m", "feeler", *verbose, "acquire", "--emulate", "--camera", str(video), "--plan",
               str(plan), "--out", str(tmp_path / out), "--no-progress"]
        done = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
        assert done.returncode == 0, done.stderr
        bad = [ln for ln in done.stderr.splitlines() if "identical to the previous frame" in ln]
        assert len(bad) == 1, done.stderr
        assert bad[0].startswith("WARNING feeler.acquire: " if verbose else "feeler: warning: "), bad


def test_why_a_campaign_stopped_is_said_in_words():
    """summary.json and the report said "(KeyboardInterrupt: )" of a Ctrl-C (an audit)."""
    from feeler.hardware.acquire.campaign import stopped_text
    from feeler.hardware.stage.errors import PortError
    assert stopped_text(KeyboardInterrupt()) == "interrupted (Ctrl-C)"
    assert stopped_text(KeyboardInterrupt("signal 15")) == "interrupted (signal 15)"
    assert stopped_text(RuntimeError()) == "stopped by an error (RuntimeError)"
    assert stopped_text(PortError("/dev/ttyUSB0", "disconnected")) == "port /dev/ttyUSB0: disconnected"


def test_a_scan_whose_stage_lags_the_plan_is_reported():
    """grbl-sim moved at 0.8-1.0 mm/s under a 2 mm/s plan: each scan covered 1.6-2.0 of its
    4 mm, the step at 2 mm was never reached, and the run said "complete" with nothing said
    (an outside test). A scan whose last sample finds the stage under 0.8 of the way the
    plan's speed puts it (accelerating at the board's $120, at most the traverse) is
    reported; one on the profile, or read late (the stage further along, or at the end), is not."""
    from feeler.hardware.acquire.campaign import SLOW_SCAN_SHARE, slow_scan

    def rows(speed, times):                      # a stage at constant ``speed`` from t = 0, stopping at 4 mm
        return [{"t_s": t, "x_mm": min(speed * t, 4.0)} for t in times]

    times = np.arange(21) * 0.1                                                   # 2 s of samples
    along, expected = slow_scan(rows(0.97, times), 2.0, 10.0, 4.0)
    assert along == pytest.approx(1.94) and expected == pytest.approx(2.0 * 2.0 - 0.5 * 2.0 * 0.2)   # 3.8 mm
    assert along < SLOW_SCAN_SHARE * expected
    assert slow_scan(rows(2.0, times), 2.0, 10.0, 4.0) is None                    # on the plan (a 0.2 s ramp)
    assert slow_scan(rows(2.0, np.r_[times, 9.0]), 2.0, 10.0, 4.0) is None        # read late: at the end, 4 mm
    assert slow_scan(rows(0.97, times)[:1], 2.0, 10.0, 4.0) is None               # one sample at t = 0
    assert slow_scan([], 2.0, 10.0, 4.0) is None
