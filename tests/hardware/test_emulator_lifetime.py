"""The emulator child dies with its parent: by PR_SET_PDEATHSIG and by its parent-pid poll."""
import multiprocessing
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

from feeler.hardware.emulators import GrblConfig
from feeler.hardware.emulators import pty_server


def _alive(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().split()[2] != "Z"     # a zombie is dead
    except FileNotFoundError:
        return False


def _gone_within(pid: int, seconds: float) -> float | None:
    """Seconds until ``pid`` is gone, or None if it still runs after ``seconds``."""
    start = time.monotonic()
    while time.monotonic() - start < seconds:
        if not _alive(pid):
            return time.monotonic() - start
        time.sleep(0.02)
    return None


PARENT = textwrap.dedent("""
    import sys, time
    from feeler.hardware.{module} import {factory}
    with {factory}() as emu:
        print(emu.process.pid if hasattr(emu, "process") else "", flush=True)
        time.sleep(60)
""")


def _kill_9_parent_of(module: str, factory: str) -> None:
    code = PARENT.format(module=module, factory=factory)
    parent = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    try:
        line = parent.stdout.readline().strip()
        kids = [int(p) for p in Path(f"/proc/{parent.pid}/task/{parent.pid}/children").read_text().split()]
        emulators = [int(line)] if line else kids
        assert emulators and all(_alive(p) for p in emulators)
        os.kill(parent.pid, signal.SIGKILL)
        parent.wait()
        waited = [_gone_within(p, 2.0) for p in emulators]
        for p, w in zip(emulators, waited):
            if w is None:
                os.kill(p, signal.SIGKILL)
        assert None not in waited, f"emulator outlived its killed parent: {waited}"
    finally:
        parent.stdout.close()
        if parent.poll() is None:
            parent.kill()
            parent.wait()


def test_emulator_process_dies_within_2_s_of_its_parents_kill_9():
    _kill_9_parent_of("emulators", "emulator_process")


def test_campaign_emulator_is_the_same_tied_child():
    _kill_9_parent_of("acquire.emulated", "campaign_emulator")


def test_child_stops_by_itself_once_its_parent_pid_is_not_the_expected_one():
    """The poll path (the fallback off Linux, and for a parent dead before prctl ran)."""
    ctx = multiprocessing.get_context("spawn")
    here, there = ctx.Pipe(duplex=False)
    wrong_parent = os.getpid() + 1_000_000          # never the child's parent pid
    child = ctx.Process(target=pty_server._child, args=(GrblConfig(), (), 0, wrong_parent, there), daemon=True)
    child.start()
    try:
        assert here.poll(30) and here.recv().startswith("/dev/")
        child.join(2.0)
        assert child.exitcode == 0
    finally:
        if child.is_alive():
            child.kill()
        child.join()
        here.close()


def test_child_serves_while_its_parent_lives():
    """Negative of the above: with the true parent pid the child keeps serving."""
    ctx = multiprocessing.get_context("spawn")
    here, there = ctx.Pipe(duplex=False)
    child = ctx.Process(target=pty_server._child, args=(GrblConfig(), (), 0, os.getpid(), there), daemon=True)
    child.start()
    try:
        assert here.poll(30) and here.recv().startswith("/dev/")
        child.join(0.5)
        assert child.is_alive()
    finally:
        child.terminate()
        child.join(5.0)
        assert child.exitcode == 0
        here.close()
