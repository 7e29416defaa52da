"""The stage driver against the Grbl emulator in a separate process, over a real pty."""
import logging

import pytest

from feeler.errors import ArgumentError
from feeler.hardware.emulators import Fault, GrblConfig, emulator_process
from feeler.hardware.stage import Stage, StageAlarm, StageDisconnected, StageLimits, StageTimeout

FAST = GrblConfig(max_rate_mm_min=(60000.0,) * 3, accel_mm_s2=(20000.0,) * 3,
                  start_mm=(0.0, 0.0, 20.0))


@pytest.fixture(scope="module")
def emu():
    with emulator_process(FAST) as process:
        yield process


def open_stage(path, **kw):
    return Stage.open(path, reply_timeout_s=kw.pop("reply_timeout_s", 0.5), poll_s=0.005, **kw)


def test_open_reads_soft_limits_from_settings(emu):
    with open_stage(emu.path) as stage:
        assert stage.limits == StageLimits((0.0, 200.0), (0.0, 200.0), (0.0, 50.0), 60000.0)
        assert stage.status().state == "Idle"


def test_move_press_and_traverse_while_sampling_position(emu):
    with open_stage(emu.path) as stage:
        stage.move_to(x_mm=10.0, y_mm=5.0, z_mm=20.0, feed_mm_min=30000.0)
        assert stage.wait_idle(5.0).mpos_mm == (10.0, 5.0, 20.0)
        assert stage.press(1.5, 6000.0) == (10.0, 5.0, 18.5)
        assert stage.position_mm() == (10.0, 5.0, 18.5)
        assert stage.traverse(20.0, 200.0) == (30.0, 5.0, 18.5)
        samples = list(stage.track(5.0))
        xs = [s.mpos_mm[0] for s in samples]
        assert samples[-1].state == "Idle" and xs[-1] == 30.0
        assert sum(s.state == "Run" for s in samples) >= 5 and xs == sorted(xs)
        assert max(s.feed_mm_min for s in samples) == pytest.approx(12000.0, abs=1.0)


def test_streamed_lines_use_flow_control_over_the_pty(emu):
    with open_stage(emu.path) as stage:
        stage.move_to(x_mm=0.0, y_mm=0.0, z_mm=0.0, feed_mm_min=60000.0)
        lines = ["G91 G1 F60000"] + [f"X0.5 Y{0.25 * (i % 2):.2f}" for i in range(80)] + ["G90"]
        replies = stage.protocol.stream(lines)
        assert len(replies) == len(lines)
        assert stage.wait_idle(10.0).mpos_mm == (40.0, 10.0, 0.0)


@pytest.mark.parametrize("kwargs, fragment", [
    ({"x_mm": 250.0, "feed_mm_min": 100.0}, "argument x_mm=250.0: within the soft limits [0, 200] mm of /dev/"),
    ({"z_mm": -1.0, "feed_mm_min": 100.0}, "argument z_mm=-1.0: within the soft limits [0, 50] mm"),
    ({"x_mm": 1.0, "feed_mm_min": 0.0}, "argument feed_mm_min=0.0: > 0 and <= 60000 mm/min on /dev/"),
    ({"x_mm": 1.0, "feed_mm_min": 1e9}, "argument feed_mm_min=1000000000.0"),
    ({"x_mm": float("nan"), "feed_mm_min": 100.0}, "argument x_mm=nan"),
])
def test_impossible_moves_are_refused_before_sending(emu, kwargs, fragment):
    with open_stage(emu.path) as stage:
        before = stage.position_mm()
        with pytest.raises(ArgumentError) as info:
            stage.move_to(**kwargs)
        assert str(info.value).startswith(fragment) and "\n" not in str(info.value)
        assert stage.position_mm() == before and not stage.protocol.in_flight


@pytest.mark.parametrize("call, name", [
    (lambda s: s.traverse(0.0, 10.0), "dx_mm"), (lambda s: s.traverse(1.0, 0.0), "speed_mm_s"),
    (lambda s: s.press(0.0, 100.0), "depth_mm"), (lambda s: s.press(100.0, 100.0), "z_mm"),
    (lambda s: s.traverse(1000.0, 10.0), "x_mm"),
])
def test_bad_relative_moves_name_the_argument(emu, call, name):
    with open_stage(emu.path) as stage:
        with pytest.raises(ArgumentError) as info:
            call(stage)
        assert info.value.name == name


def test_feed_hold_and_resume(emu):
    with open_stage(emu.path) as stage:
        stage.move_to(x_mm=0.0, feed_mm_min=60000.0)
        stage.wait_idle(5.0)
        stage.traverse(30.0, 50.0)
        # hold once the move is under way (a loaded machine may answer before it starts)
        next(s for s in stage.track(5.0) if s.state == "Run" and s.mpos_mm[0] > 0.0)
        stage.hold()
        held = next(s for s in stage.track(5.0) if s.state == "Hold" and s.substate == 0)
        assert 0.0 < held.mpos_mm[0] < 30.0 and stage.status().mpos_mm == held.mpos_mm
        stage.resume()
        assert stage.wait_idle(5.0).mpos_mm[0] == 30.0


@pytest.mark.parametrize("fault", [
    Fault("drop", reply="ok", nth=3), Fault("garble", reply="ok", nth=3),
    Fault("truncate", reply="ok", nth=3),
], ids=["dropped ok", "garbled ok", "truncated ok"])
def test_lost_acknowledgement_of_a_move_is_resent(fault, caplog):
    with emulator_process(FAST, faults=(fault,)) as emu, open_stage(emu.path, reply_timeout_s=0.3) as stage:
        # open used ok #1 ($$) and ok #2 (G21 G90): the move's ok is the third
        with caplog.at_level(logging.WARNING, logger="feeler.hardware.stage"):
            stage.move_to(x_mm=7.0, feed_mm_min=30000.0)
        assert "re-sending 'G90 G1 X7.0000 F30000.0'" in caplog.text
        assert stage.wait_idle(5.0).mpos_mm == (7.0, 0.0, 20.0)


@pytest.mark.parametrize("fault", [
    Fault("drop", reply="status", nth=2), Fault("garble", reply="status", nth=2),
    Fault("truncate", reply="status", nth=2), Fault("delay", reply="status", nth=2, delay_s=0.5),
], ids=["dropped", "garbled", "truncated", "delayed"])
def test_damaged_status_report_is_retried(fault):
    with emulator_process(FAST, faults=(fault,)) as emu, open_stage(emu.path, reply_timeout_s=0.3) as stage:
        for _ in range(3):  # the first report was read by open
            assert stage.position_mm() == (0.0, 0.0, 20.0)


def test_status_never_answered_is_a_timeout():
    with emulator_process(FAST, faults=(Fault("drop", reply="status", nth=None),)) as emu:
        with pytest.raises(StageTimeout, match="no status report from /dev/"):
            open_stage(emu.path, reply_timeout_s=0.1)


def test_alarm_at_a_position_then_recover_and_continue():
    with emulator_process(FAST, faults=(Fault("alarm", code=1, x_mm=5.0),)) as emu, \
            open_stage(emu.path) as stage:
        stage.move_to(x_mm=10.0, feed_mm_min=30000.0)
        with pytest.raises(StageAlarm) as info:
            stage.wait_idle(5.0)
        assert info.value.code == 1
        assert stage.recover().state == "Idle"
        assert stage.position_mm() == (5.0, 0.0, 20.0)
        stage.move_to(x_mm=10.0, feed_mm_min=30000.0)
        assert stage.wait_idle(5.0).mpos_mm == (10.0, 0.0, 20.0)


def test_vanished_port_is_disconnected():
    with emulator_process(FAST, faults=(Fault("vanish", reply="status", nth=4),)) as emu, \
            open_stage(emu.path) as stage:
        stage.position_mm()  # open read reports 1 and 2; this is 3, the 4th vanishes
        with pytest.raises(StageDisconnected, match=f"port {emu.path} disconnected"):
            stage.position_mm()
        emu.process.join(5.0)
        assert not emu.alive()
