"""The stage driver against the Grbl emulator in a separate process, over a real pty.

Machine coordinates follow Grbl's convention (soft limits on [-travel, 0]).
"""
import logging
import time
from pathlib import Path

import pytest

from feeler.errors import ArgumentError
from feeler.hardware.acquire.session import DEFAULT_BOARD_NOTE as NOTE   # tiny plans' fast moves get it
from feeler.hardware.emulators import Fault, GrblConfig, emulator_process
from feeler.hardware.stage import (ProtocolError, Stage, StageAlarm, StageDisconnected, StageLimits, StageLocked,
                                   StageTimeout)

FAST = GrblConfig(max_rate_mm_min=(60000.0,) * 3, accel_mm_s2=(20000.0,) * 3, start_mm=(0.0, 0.0, -20.0))


@pytest.fixture(scope="module")
def emu():
    with emulator_process(FAST) as process:
        yield process


def open_stage(path, **kw):
    return Stage.open(path, reply_timeout_s=kw.pop("reply_timeout_s", 0.5), poll_s=0.005, **kw)


def test_open_reads_soft_limits_from_settings_in_grbls_convention(emu):
    with open_stage(emu.path) as stage:
        assert stage.limits == StageLimits((-200.0, 0.0), (-200.0, 0.0), (-200.0, 0.0), (60000.0,) * 3,
                                           (20000.0,) * 3)
        assert stage.status().state == "Idle" and not stage.locked


def test_move_press_and_traverse_while_sampling_position(emu):
    with open_stage(emu.path) as stage:
        stage.move_to(x_mm=-30.0, y_mm=-5.0, z_mm=-20.0, feed_mm_min=30000.0)
        assert stage.wait_idle().mpos_mm == (-30.0, -5.0, -20.0)
        assert stage.press(1.5, 6000.0) == (-30.0, -5.0, -21.5)
        assert stage.position_mm() == (-30.0, -5.0, -21.5)
        assert stage.traverse(20.0, 200.0) == (-10.0, -5.0, -21.5)
        samples = list(stage.track())
        xs = [s.mpos_mm[0] for s in samples]
        assert samples[-1].state == "Idle" and xs[-1] == -10.0
        assert sum(s.state == "Run" for s in samples) >= 5 and xs == sorted(xs)
        assert max(s.feed_mm_min for s in samples) == pytest.approx(12000.0, abs=1.0)


def test_streamed_lines_use_flow_control_over_the_pty(emu):
    with open_stage(emu.path) as stage:
        stage.move_to(x_mm=-40.0, y_mm=-10.0, z_mm=0.0, feed_mm_min=60000.0)
        lines = ["G91 G1 F60000"] + [f"X0.5 Y{0.25 * (i % 2):.2f}" for i in range(80)] + ["G90"]
        replies = stage.protocol.stream(lines)
        assert len(replies) == len(lines)
        stage.target_mm = (0.0, 0.0, 0.0)
        assert stage.wait_idle().mpos_mm == (0.0, 0.0, 0.0)


@pytest.mark.parametrize("kwargs, fragment", [
    ({"x_mm": 5.0, "feed_mm_min": 100.0}, "argument x_mm=5.0: within the soft limits [-200, 0] mm of /dev/"),
    ({"z_mm": -201.0, "feed_mm_min": 100.0}, "argument z_mm=-201.0: within the soft limits [-200, 0] mm"),
    ({"x_mm": -1.0, "feed_mm_min": 0.0}, "argument feed_mm_min=0.0: a feed > 0 mm/min on /dev/"),
    ({"x_mm": -1.0, "feed_mm_min": 1e9}, "argument feed_mm_min=1000000000.0: <= 60000 mm/min for this move on "
                                         "/dev/"),
    ({"x_mm": float("nan"), "feed_mm_min": 100.0}, "argument x_mm=nan"),
])
def test_impossible_moves_are_refused_before_sending(emu, kwargs, fragment):
    with open_stage(emu.path) as stage:
        before = stage.position_mm()
        with pytest.raises(ArgumentError) as info:
            stage.move_to(**kwargs)
        assert str(info.value).startswith(fragment) and "\n" not in str(info.value)
        assert stage.position_mm() == before and not stage.protocol.in_flight


def test_feed_ceiling_names_the_axis_setting():
    with emulator_process(GrblConfig(max_rate_mm_min=(3000.0, 500.0, 500.0))) as emu, open_stage(emu.path) as stage:
        stage.move_to(x_mm=-10.0, feed_mm_min=3000.0)                  # x alone may go at 3000
        with pytest.raises(ArgumentError, match=r"<= 500 mm/min for this move on .* \(\$111, the y axis' "
                                                r"maximum rate, is 500 mm/min\)"):
            stage.move_to(y_mm=-10.0, feed_mm_min=3000.0)


@pytest.mark.parametrize("call, name", [
    (lambda s: s.traverse(0.0, 10.0), "dx_mm"), (lambda s: s.traverse(1.0, 0.0), "speed_mm_s"),
    (lambda s: s.press(0.0, 100.0), "depth_mm"), (lambda s: s.press(500.0, 100.0), "z_mm"),
    (lambda s: s.traverse(1000.0, 10.0), "x_mm"),
])
def test_bad_relative_moves_name_the_argument(emu, call, name):
    with open_stage(emu.path) as stage:
        with pytest.raises(ArgumentError) as info:
            call(stage)
        assert info.value.name == name


def test_axes_that_do_not_move_are_not_checked():
    """At (1, 1, 1), outside [-200, 0] (a board without soft limits may stand anywhere), a
    move of z alone is fine; so is one to a negative z after homing at -$27."""
    with emulator_process(GrblConfig(start_mm=(1.0, 1.0, 1.0), max_rate_mm_min=(6000.0,) * 3,
                                     accel_mm_s2=(1000.0,) * 3)) as emu, open_stage(emu.path) as stage:
        stage.move_to(z_mm=-2.0, feed_mm_min=3000.0)
        assert stage.wait_idle().mpos_mm == (1.0, 1.0, -2.0)


def test_feed_hold_and_resume(emu):
    with open_stage(emu.path) as stage:
        stage.move_to(x_mm=-60.0, feed_mm_min=60000.0)
        stage.wait_idle()
        stage.traverse(30.0, 50.0)
        # hold once the move is under way (a loaded machine may answer before it starts)
        next(s for s in stage.track() if s.state == "Run" and s.mpos_mm[0] > -60.0)
        stage.hold()
        stage.resume()                       # waits for Hold:0 (Grbl ignores ~ during Hold:1)
        assert stage.wait_idle().mpos_mm[0] == -30.0


def test_work_positions_are_turned_into_machine_positions():
    config = GrblConfig(settings=((10, 0),), max_rate_mm_min=(6000.0,) * 3, accel_mm_s2=(1000.0,) * 3)
    with emulator_process(config) as emu, open_stage(emu.path) as stage:
        stage.protocol.send("G10 L20 P1 X5 Y5 Z5")                     # work offsets: reports differ
        stage.move_to(x_mm=-3.0, feed_mm_min=3000.0)
        status = stage.wait_idle()
        assert status.mpos_mm == (-3.0, 0.0, 0.0) and status.wpos_mm == (2.0, 5.0, 5.0)
        assert [stage.position_mm() for _ in range(12)] == [(-3.0, 0.0, 0.0)] * 12


def test_a_locked_board_is_refused_unless_unlocked_or_homed():
    with emulator_process(GrblConfig(settings=((22, 1), (24, 600.0), (25, 3000.0)))) as emu:
        with pytest.raises(StageLocked, match="is locked .*homing is enabled .*: home it .* or unlock it"):
            open_stage(emu.path)
        with open_stage(emu.path, unlock=True) as stage:
            assert stage.status().state == "Idle" and not stage.locked
        with open_stage(emu.path, home=True, reply_timeout_s=1.0) as stage:
            assert stage.position_mm() == (-1.0, -1.0, -1.0)
            stage.move_to(z_mm=-2.0, feed_mm_min=300.0)              # the case 3
            assert stage.wait_idle().mpos_mm == (-1.0, -1.0, -2.0)


def test_dwell_longer_than_the_reply_timeout():
    with emulator_process(FAST) as emu, open_stage(emu.path, reply_timeout_s=0.2) as stage:
        start = time.monotonic()
        stage.protocol.send("G4 P1.2")
        assert time.monotonic() - start >= 1.2


def test_a_full_planner_is_waited_for_never_re_sent(caplog):
    """Sixteen 0.3 s moves against a 0.2 s reply timeout: the oks follow the planner."""
    slow = GrblConfig(max_rate_mm_min=(600.0,) * 3, accel_mm_s2=(10000.0,) * 3)
    with emulator_process(slow) as emu, open_stage(emu.path, reply_timeout_s=0.2) as stage:
        with caplog.at_level(logging.WARNING, logger="feeler.hardware.stage"):
            for i in range(1, 21):
                stage.move_to(x_mm=-3.0 * i, feed_mm_min=600.0)
        assert caplog.text == "" and not [k for k in stage.recovered if not k.startswith("status_")]
        assert stage.wait_idle().mpos_mm == (-60.0, 0.0, 0.0)


@pytest.mark.parametrize("fault", [
    Fault("drop", reply="ok", nth=4), Fault("garble", reply="ok", nth=4), Fault("truncate", reply="ok", nth=4),
], ids=["dropped ok", "garbled ok", "truncated ok"])
def test_a_move_whose_reply_was_lost_is_not_sent_again(fault, caplog):
    with emulator_process(FAST, faults=(fault,)) as emu, open_stage(emu.path, reply_timeout_s=0.3) as stage:
        # open used ok #1 ($$), #2 ($I), #3 (G21 G90): the move's ok is the fourth
        with caplog.at_level(logging.WARNING, logger="feeler.hardware.stage"):
            stage.move_to(x_mm=-7.0, feed_mm_min=30000.0)
        assert "waiting for the stage to settle" in caplog.text and "sending it again" not in caplog.text
        assert stage.wait_idle().mpos_mm == (-7.0, 0.0, -20.0)


def test_a_move_that_never_arrived_is_sent_again(caplog):
    with emulator_process(FAST, faults=(Fault("lose", nth=4),)) as emu, \
            open_stage(emu.path, reply_timeout_s=0.3) as stage:
        with caplog.at_level(logging.WARNING, logger="feeler.hardware.stage"):
            stage.move_to(x_mm=-7.0, feed_mm_min=30000.0)
        assert "never received 'G53 G1 X-7.0000 F30000.0'; sending it again" in caplog.text
        assert stage.wait_idle().mpos_mm == (-7.0, 0.0, -20.0)
        assert stage.recovered == {"ok_lost": 1}


@pytest.mark.parametrize("fault", [
    Fault("drop", reply="status", nth=2), Fault("garble", reply="status", nth=2),
    Fault("truncate", reply="status", nth=2), Fault("delay", reply="status", nth=2, delay_s=0.5),
], ids=["dropped", "garbled", "truncated", "delayed"])
def test_damaged_status_report_is_retried(fault):
    with emulator_process(FAST, faults=(fault,)) as emu, open_stage(emu.path, reply_timeout_s=0.3) as stage:
        for _ in range(3):  # the first report was read by open
            assert stage.position_mm() == (0.0, 0.0, -20.0)


def test_status_never_answered_is_a_timeout():
    with emulator_process(FAST, faults=(Fault("drop", reply="status", nth=None),)) as emu:
        with pytest.raises(StageTimeout, match="no status report from /dev/"):
            open_stage(emu.path, reply_timeout_s=0.1)


@pytest.mark.parametrize("code", [1, 2])
def test_critical_alarm_then_recover_at_once_and_continue(code):
    with emulator_process(FAST, faults=(Fault("alarm", code=code, x_mm=-5.0),)) as emu, \
            open_stage(emu.path) as stage:
        stage.move_to(x_mm=-10.0, feed_mm_min=30000.0)
        with pytest.raises(StageAlarm) as info:
            stage.wait_idle()
        assert info.value.code == code
        assert stage.recover().state == "Idle"             # straight away: in the 0.5 s silence
        assert stage.position_mm() == (-5.0, 0.0, -20.0)
        stage.move_to(x_mm=-10.0, feed_mm_min=30000.0)
        assert stage.wait_idle().mpos_mm == (-10.0, 0.0, -20.0)


def test_soft_limit_alarm_of_the_firmware_then_recover():
    config = GrblConfig(settings=((22, 1), (20, 1)), max_rate_mm_min=(6000.0,) * 3, accel_mm_s2=(1000.0,) * 3)
    limits = StageLimits((-200.0, 50.0), (-200.0, 0.0), (-200.0, 0.0), (6000.0,) * 3, (1000.0,) * 3)
    with emulator_process(config) as emu, open_stage(emu.path, unlock=True, limits=limits) as stage:
        with pytest.raises(StageAlarm, match="ALARM:2"):
            stage.move_to(x_mm=5.0, feed_mm_min=3000.0)      # the driver was told wrong limits
        status = stage.recover()
        assert status.state == "Idle" and status.mpos_mm == (0.0, 0.0, 0.0)


def test_jog_and_jog_cancel(emu):
    with open_stage(emu.path) as stage:
        stage.move_to(x_mm=0.0, feed_mm_min=60000.0)
        stage.wait_idle()
        stage.jog_to(x_mm=-50.0, feed_mm_min=600.0)
        assert next(s for s in stage.track() if s.mpos_mm[0] < -0.5).state == "Jog"
        with pytest.raises(ProtocolError, match="error:9"):
            stage.protocol.send("G4 P0")                   # G-code is locked out while jogging
        status = stage.jog_cancel()
        assert status.state == "Idle" and -50.0 < status.mpos_mm[0] < -0.5
        assert stage.target_mm == status.mpos_mm


def test_vanished_port_is_disconnected():
    with emulator_process(FAST, faults=(Fault("vanish", reply="status", nth=5),)) as emu, \
            open_stage(emu.path) as stage:
        stage.position_mm(), stage.position_mm()  # open read reports 1-2 (before and after its reset); these are 3
        # and 4; the 5th vanishes
        with pytest.raises(StageDisconnected, match=f"port {emu.path} disconnected"):
            stage.position_mm()
        emu.process.join(5.0)
        assert not emu.alive()


def test_a_board_older_than_grbl_1_1_is_named_before_anything_is_sent():
    """Grbl 0.9 answers $$ with '$0=10 (step pulse, usec)' and reports '<Idle,MPos:...,WPos:...>':
    the driver stopped at 'malformed reply: b'$0=10 (step pulse, usec)''. Its banner now
    names the version and what to do (the emulator serves 1.1 replies under a 0.9j banner)."""
    from feeler.hardware.stage import PortError
    from feeler.hardware.stage.device import _check_version

    with emulator_process(GrblConfig(version="0.9j")) as old:
        with pytest.raises(PortError, match=r"runs Grbl 0\.9j, and feeler speaks Grbl 1\.1 .* flash Grbl 1\.1h"):
            open_stage(old.path)
    for version in ("1.1h", "1.1f", "1.2", "2.0a", "custom"):
        _check_version("p", version)
    with pytest.raises(PortError, match="Grbl 0.8c"):
        _check_version("p", "0.8c")


class _NotGrbl:
    """A pty that is no Grbl 1.1 board: it says nothing, or answers every write with
    ``answer`` (line noise of a wrong baud rate, another firmware's text)."""

    def __init__(self, answer: bytes = b""):
        import os
        import pty
        import threading
        import tty

        self.master, slave = pty.openpty()
        tty.setraw(slave)
        self.path, self._slave, self.answer = os.ttyname(slave), slave, answer
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self):
        import os
        import select

        while not self._stop.is_set():
            if select.select([self.master], [], [], 0.05)[0]:
                try:
                    os.read(self.master, 1024)
                except OSError:
                    return
                if self.answer:
                    os.write(self.master, self.answer)

    def close(self):
        import os

        self._stop.set()
        self._thread.join(2)
        os.close(self.master)
        os.close(self._slave)


@pytest.mark.parametrize("answer, words", [
    (b"", "nothing came back: is this the board's port, and is the board powered?"),
    (bytes([0xF0, 0x8C, 0x3E, 0xFE, 0x00, 0x7F, 0xE6]) * 20,
     r"bytes that are not text came back \(b'\\xf0\\x8c>.*\.\.\. \(140 bytes\)\): the board talks at another "
     r"baud rate than 115200\?$"),
    (b'echo:Unknown command: "\x18"\nok\n', r"it answered b'echo:Unknown command: .*', not Grbl's banner: is this "
                                            r"a Grbl 1\.1 board\?$"),
])
def test_a_port_that_is_no_grbl_board_says_what_came_back(answer, words):
    """It said 'no banner after reset within 3.99978 s' (with the whole of a baud-rate
    mismatch's noise as a 'short read'), and the CLI offered --resume for a run never begun."""
    from feeler.hardware.stage import PortError

    board = _NotGrbl(answer)
    try:
        with pytest.raises(PortError, match=rf"^port {board.path}: no Grbl banner within 1 s of a reset \(Ctrl-X\); "
                                            + words):
            Stage.open(board.path, reply_timeout_s=0.5, slack=1.0)
    finally:
        board.close()


def test_the_cli_offers_resume_only_for_a_run_it_began(tmp_path, capsys):
    """A port that is no Grbl board failed before the run began, and the CLI still said 'the
    run so far is kept: run the same command with --resume'; it says so only when the run's
    journal exists (a port vanishing mid-run)."""
    import argparse

    from feeler.cli import _run_started, main

    begun = argparse.Namespace(resume=False, out=str(tmp_path / "r"))
    assert not _run_started(begun)                                  # nothing written yet
    (tmp_path / "r").mkdir()
    (tmp_path / "r" / "journal.jsonl").write_text("{}\n")
    assert _run_started(begun) and not _run_started(argparse.Namespace(out=str(tmp_path / "r")))   # not acquire
    plan = str(Path(__file__).parent / "data" / "tiny-plan.toml")
    assert main(["acquire", "--emulate", "--plan", plan, "--out", str(tmp_path / "run"), "--no-progress",
                 "--fault", "vanish:reply=ok,nth=8"]) == 1     # the port vanishes mid-run
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("feeler:") and not ln.startswith(NOTE)]
    assert len(err) == 1 and "disconnected" in err[0]
    assert err[0].endswith("the run so far is kept: run the same command with --resume to continue")
    assert (tmp_path / "run" / "journal.jsonl").is_file()


def test_opening_a_board_still_moving_for_a_killed_process_holds_it_and_keeps_the_position():
    """``kill -9`` during a traverse leaves the board running the queued moves; the next
    process's opening reset in motion raised ALARM:3 (position lost) and ``acquire
    --resume`` refused the locked stage (an outside test on grbl-sim). Opening now feed-holds
    a moving board and resets once the hold is complete: no alarm, the position kept."""
    with emulator_process(FAST) as emu:
        first = open_stage(emu.path)
        first.move_to(x_mm=-50.0, feed_mm_min=600.0)                  # 5 s of motion
        next(s for s in first.track() if s.mpos_mm[0] < -1.0)
        first.close()                                                  # killed: nothing stops the board
        with open_stage(emu.path) as second:
            status = second.status()
            assert not second.locked and status.state == "Idle" and second.protocol.last_alarm is None
            assert -50.0 < status.mpos_mm[0] < -1.0                    # where the hold stopped it
        with open_stage(emu.path) as idle:                             # an idle board: opened as before
            assert idle.status().mpos_mm == status.mpos_mm
