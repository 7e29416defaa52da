"""Real-time priority for the acquisition loop: granted, refused, restored, not inherited."""
import os
import subprocess
import sys

import pytest

from feeler.errors import ArgumentError
from feeler.hardware.acquire.session import DEFAULT_BOARD_NOTE as NOTE   # tiny plans' fast moves get it
from feeler.hardware.realtime import DEFAULT_PRIORITY, realtime_priority

CHILD_POLICY = "import os; print(os.sched_getscheduler(0))"


def _may_use_realtime() -> bool:
    import resource
    return os.geteuid() == 0 or resource.getrlimit(resource.RLIMIT_RTPRIO)[0] >= DEFAULT_PRIORITY


@pytest.mark.skipif(not _may_use_realtime(), reason="needs root or an rtprio limit >= 10")
def test_granted_block_runs_fifo_children_start_normal_and_the_policy_is_restored():
    before = os.sched_getscheduler(0)
    with realtime_priority() as refused:
        assert refused is None
        assert os.sched_getscheduler(0) == os.SCHED_FIFO | os.SCHED_RESET_ON_FORK
        assert os.sched_getparam(0).sched_priority == DEFAULT_PRIORITY
        child = subprocess.run([sys.executable, "-c", CHILD_POLICY], capture_output=True, text=True, check=True)
        assert int(child.stdout) == os.SCHED_OTHER          # the emulator and workers start at the normal policy
    assert os.sched_getscheduler(0) == before


def test_refused_block_says_why_in_one_line_and_runs_as_usual(monkeypatch):
    def refuse(*_):
        raise PermissionError(1, "Operation not permitted")

    monkeypatch.setattr(os, "sched_setscheduler", refuse)
    before = os.sched_getscheduler(0)
    with realtime_priority(20) as refused:
        assert refused.startswith("real-time priority 20 not permitted (needs root, CAP_SYS_NICE")
        assert "ulimit -r is" in refused and "\n" not in refused
        assert os.sched_getscheduler(0) == before


def test_refused_without_the_capability_in_a_real_process():
    """A process without CAP_SYS_NICE and with the default rtprio limit 0: the kernel
    itself refuses, the block says so and runs at the normal policy."""
    import shutil

    if os.geteuid() != 0 or shutil.which("setpriv") is None:
        pytest.skip("needs root and setpriv to start a process without CAP_SYS_NICE")
    code = ("from feeler.hardware.realtime import realtime_priority\n"
            "import os, resource\n"
            "resource.setrlimit(resource.RLIMIT_RTPRIO, (0, 0))\n"
            "with realtime_priority() as r:\n"
            "    print(r); print(os.sched_getscheduler(0))\n")
    out = subprocess.run(["setpriv", "--bounding-set", "-sys_nice", sys.executable, "-c", code],
                         capture_output=True, text=True, check=True).stdout.splitlines()
    assert out[0] == "real-time priority 10 not permitted (needs root, CAP_SYS_NICE or a real-time priority limit: " \
                     "ulimit -r is 0)"
    assert int(out[1]) == os.SCHED_OTHER


@pytest.mark.parametrize("bad", [0, 100, 5.0, "10"])
def test_priority_outside_1_to_99_is_refused(bad):
    with pytest.raises(ArgumentError, match="priority"):
        with realtime_priority(bad):
            pass


def test_acquire_realtime_runs_the_campaign_and_says_what_it_got(tmp_path, capsys):
    """``feeler acquire --emulate --realtime``: one line on stderr (granted, or why not),
    the campaign completes, and the main thread is back at its policy afterwards."""
    from pathlib import Path

    from feeler.cli import main

    plan = tmp_path / "one.toml"
    tiny = Path(__file__).parent / "data" / "tiny-plan.toml"
    plan.write_text(tiny.read_text().replace("heights_mm = [0.0, 0.2]", "heights_mm = [0.0]")
                    .replace("origin_x_mm = [-20.0, -16.0]", "origin_x_mm = [-20.0]")
                    .replace("scans_per_plate = 2", "scans_per_plate = 1"))
    before = os.sched_getscheduler(0)
    assert main(["acquire", "--emulate", "--realtime", "--no-progress", "--plan", str(plan),
                 "--out", str(tmp_path / "run")]) == 0
    captured = capsys.readouterr()
    said = [ln for ln in captured.err.splitlines() if ln.startswith("feeler:") and not ln.startswith(NOTE)]
    expected = ("feeler: acquisition loop at real-time priority (SCHED_FIFO 10)" if _may_use_realtime() else
                "feeler: real-time priority 10 not permitted")
    assert len(said) == 1 and said[0].startswith(expected)
    assert "1 of 1 scans (complete)" in captured.out
    assert os.sched_getscheduler(0) == before
