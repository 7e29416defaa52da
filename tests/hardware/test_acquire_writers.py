"""One writer per run directory: a second writer is refused naming the first one's PID, the
lock dies with its process (kill -9 leaves nothing to clean), racing resumes never double
a sample."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

from feeler.cli import main
from feeler.hardware.acquire.lock import RunLocked, lock_run_dir, release_run_dir
from feeler.hardware.acquire.session import DEFAULT_BOARD_NOTE as NOTE   # tiny plans' fast moves get it

DATA = Path(__file__).parent / "data"
TINY = DATA / "tiny-plan.toml"


def acquire_process(run: Path, *extra: str, plan: Path = TINY) -> subprocess.Popen:
    cmd = [sys.executable, "-m", "feeler", "acquire", "--emulate", "--plan", str(plan), "--out", str(run),
           "--no-progress", *extra]
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def wait_for_rows(proc: subprocess.Popen, samples: Path, rows: int, timeout_s: float = 120.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not (samples.exists() and samples.read_text().count("\n") >= 1 + rows):
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, "the campaign wrote nothing"
        time.sleep(0.01)


def no_doubles(run: Path) -> pd.DataFrame:
    scans = pd.read_csv(run / "scans.csv")
    assert not scans.duplicated(["scan_id", "t_sched_s"]).any()
    return scans


def test_the_lock_names_its_holder_and_is_released_on_close(tmp_path):
    fd = lock_run_dir(tmp_path / "run")
    with pytest.raises(RunLocked) as info:
        lock_run_dir(tmp_path / "run")
    assert info.value.pid == os.getpid() and f"process {os.getpid()} is writing" in str(info.value)
    release_run_dir(fd)
    release_run_dir(lock_run_dir(tmp_path / "run"))


def test_a_second_writer_is_refused_while_the_first_runs(tmp_path, capsys):
    """A slow campaign (4 scans of 31 samples) is running; ``--resume`` and ``--force`` into
    its directory are refused with one line naming its PID, and change nothing."""
    slow = tmp_path / "slow.toml"
    slow.write_text(TINY.read_text().replace("speed_mm_s = 10.0", "speed_mm_s = 1.0"))
    run = tmp_path / "run"
    first = acquire_process(run, plan=slow)
    try:
        wait_for_rows(first, run / "samples.csv", 2)
        for extra in (["--resume"], ["--force"]):
            assert main(["acquire", "--emulate", "--plan", str(slow), "--out", str(run), "--no-progress", *extra]) == 2
            err = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("feeler:")
                   and not ln.startswith(NOTE)]
            assert err == [f"feeler: error: {run}: process {first.pid} is writing this run directory (one writer "
                           "at a time); wait for it to finish or stop it, then --resume"]
            assert first.poll() is None, "the first writer stopped: the refusal proves nothing"
        first.send_signal(signal.SIGTERM)
        first.communicate(timeout=60)
    finally:
        if first.poll() is None:
            first.kill()
            first.wait()
    samples = pd.read_csv(run / "samples.csv")
    assert set(samples.attempt) == {0} and not samples.duplicated(["scan_id", "t_sched_s"]).any()
    assert json.loads((run / "summary.json").read_text())["runs"] == 1


def test_kill_9_releases_the_lock_and_racing_resumes_never_double_a_sample(tmp_path):
    run = tmp_path / "run"
    first = acquire_process(run)
    wait_for_rows(first, run / "samples.csv", 6)
    os.kill(first.pid, signal.SIGKILL)
    first.communicate()
    racers = [acquire_process(run, "--resume") for _ in range(2)]
    results = [(p.pid, *p.communicate(timeout=180), p.returncode) for p in racers]
    winners = [r for r in results if r[3] == 0]
    assert winners and all("4 of 4 scans (complete)" in out for _, out, _, _ in winners)
    for pid, out, err, code in results:
        if code != 0:                                   # lost the race: refused, naming the winner
            other = next(p for p, *_ in results if p != pid)
            assert code == 2 and f"process {other} is writing this run directory" in err
    assert len(no_doubles(run)) == 16
    summary = json.loads((run / "summary.json").read_text())
    assert summary["complete"] and summary["samples_written"] == 16
