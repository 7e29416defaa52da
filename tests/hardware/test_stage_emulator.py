"""The Grbl emulator on a virtual clock: bytes in -> bytes out, exactly.

What the firmware recording cannot pin (``test_emulator_replay.py`` holds the emulator to
the real firmware byte for byte): positions against time, the planner's depth, the receive
buffer, what the emulator leaves out, homing on a board with switches, injected faults.
"""
import pytest

from feeler.hardware.emulators import Fault, GrblConfig, GrblEmulator

BANNER = b"\r\nGrbl 1.1h ['$' for help]\r\n"
# 10 mm/s along x with 100 mm/s^2: 0.1 s ramps, 0.9 s cruise for 10 mm; 1000 steps/mm
SLOW = GrblConfig(max_rate_mm_min=(6000.0, 600.0, 6000.0), accel_mm_s2=(100.0, 100.0, 100.0),
                  settings=((100, 1000.0), (101, 1000.0), (102, 1000.0)))


def talk(emu, data: bytes, now: float) -> bytes:
    emu.receive(data, now)
    emu.tick(now)
    return emu.pop_output(now)


def run(emu, t0: float, t1: float, dt: float = 0.001) -> bytes:
    out, now = b"", t0
    while now < t1:
        now += dt
        emu.tick(now)
        out += emu.pop_output(now)
    return out


def fresh(config=SLOW, faults=(), seed=0):
    emu = GrblEmulator(config, faults, seed)
    assert emu.pop_output(0.0) == BANNER
    return emu


def test_trapezoidal_move_reported_in_real_time_in_whole_steps():
    emu = fresh()
    assert talk(emu, b"G1 X-10 F600\n", 0.0) == b"ok\r\n"
    assert talk(emu, b"?", 0.05) == b"<Run|MPos:-0.125,0.000,0.000|FS:300,0|WCO:0.000,0.000,0.000>\r\n"
    assert talk(emu, b"?", 0.6) == b"<Run|MPos:-5.500,0.000,0.000|FS:600,0|Ov:100,100,100>\r\n"
    assert talk(emu, b"?", 1.05) == b"<Run|MPos:-9.875,0.000,0.000|FS:300,0>\r\n"
    assert talk(emu, b"?", 1.2) == b"<Idle|MPos:-10.000,0.000,0.000|FS:0,0>\r\n"
    emu = fresh(GrblConfig())                                       # 250 steps/mm: 0.004 mm
    talk(emu, b"G1 X-0.25 Z-0.0019 F100\n", 0.0)
    run(emu, 0.0, 5.0)
    assert talk(emu, b"?", 5.0).startswith(b"<Idle|MPos:-0.252,0.000,0.000|")   # lround(-62.5) = -63 steps


def test_rapid_is_limited_per_axis():
    emu = fresh()  # y is limited to 600 mm/min = 10 mm/s, x to 100 mm/s
    talk(emu, b"G0 X-10 Y-10\n", 0.0)
    # path rate limited so y moves at 10 mm/s: |u_y| = 1/sqrt(2) -> path 14.14 mm/s
    report = talk(emu, b"?", 0.5)
    assert report.startswith(b"<Run|") and b"|FS:849,0|" in report
    assert emu.machine.pos[0] == pytest.approx(emu.machine.pos[1])


def test_feed_hold_decelerates_and_cycle_start_resumes():
    emu = fresh()
    talk(emu, b"G1 X-10 F600\n", 0.0)
    talk(emu, b"!", 0.6)  # at 5.5 mm, 10 mm/s: stops 0.5 mm later after 0.1 s
    talk(emu, b"~", 0.62)  # ignored while decelerating
    assert talk(emu, b"?", 0.65).startswith(b"<Hold:1|")
    assert talk(emu, b"?", 0.8).startswith(b"<Hold:0|MPos:-6.000,0.000,0.000|FS:0,0")
    assert talk(emu, b"G4 P0\n", 0.9) == b""                         # suspended until resumed
    talk(emu, b"~", 1.0)
    assert talk(emu, b"?", 1.05).startswith(b"<Run|MPos:-6.125,0.000,0.000|FS:300,0")
    assert run(emu, 1.05, 1.7) == b"ok\r\n" and emu.machine.pos == (-10.0, 0.0, 0.0)


def test_dwell_is_answered_after_motion_and_delay():
    emu = fresh()
    talk(emu, b"G1 X-10 F600\nG4 P0.5\n", 0.0)
    assert emu.pop_output(0.0) == b""  # the first ok came with the talk above
    assert run(emu, 0.0, 1.59) == b""                                   # 1.1 s of motion, 0.5 s of dwell
    assert run(emu, 1.59, 1.62) == b"ok\r\n"


def test_planner_acknowledges_fifteen_blocks_ahead():
    emu = fresh()
    assert talk(emu, b"G1F600\n", 0.0) == b"ok\r\n"
    lines = b"".join(f"X-{i}\n".encode() for i in range(1, 18))  # 17 moves, 1 mm each
    assert len(lines) <= 127
    assert talk(emu, lines, 0.0) == b"ok\r\n" * 15
    assert talk(emu, b"?", 0.0).startswith(b"<Run|")
    assert run(emu, 0.0, 0.19) == b""                          # the first 1 mm block takes 0.2 s
    assert run(emu, 0.19, 0.21) == b"ok\r\n"


def test_receive_buffer_overflow_loses_bytes():
    emu = fresh()
    talk(emu, b"G4 P10\n", 0.0)  # the dwell blocks line execution
    talk(emu, b"G0 X-1\n" * 30, 0.1)
    assert emu.lost_bytes == 30 * 7 - 127
    emu = fresh(GrblConfig(settings=((10, 2),)))
    talk(emu, b"G4 P10\n", 0.0)
    talk(emu, b"G0 X-1\n" * 3, 0.1)
    assert b"|Bf:15,107|" in talk(emu, b"?", 0.1)


@pytest.mark.parametrize("line, code", [
    (b"G2 X1 Y1 I1 F100", 20), (b"G3 X1 R5 F100", 20), (b"G38.2 Z-1 F10", 20), (b"G93", 20),
    (b"$SLP", 3), (b"$N0=G0X0", 3), (b"$I=mine", 3),
])
def test_what_the_emulator_leaves_out_is_refused_never_a_silent_ok(line, code):
    emu = fresh()
    assert talk(emu, line + b"\n", 0.0) == f"error:{code}\r\n".encode()
    assert emu.machine.pos == (0.0, 0.0, 0.0) and emu.state == "Idle"


def test_homing_on_a_board_with_switches_ends_at_minus_pull_off():
    emu = GrblEmulator(GrblConfig(settings=((22, 1),)))
    assert emu.pop_output(0.0) == BANNER + b"[MSG:'$H'|'$X' to unlock]\r\n"
    assert talk(emu, b"G0 X-1\n", 0.0) == b"error:9\r\n"
    assert talk(emu, b"$H\n", 0.1) == b""
    assert talk(emu, b"?", 0.2) == b""                               # no reports while homing
    out = run(emu, 0.2, 30.0, dt=0.01)
    assert out == b"ok\r\n" and emu.state == "Idle"
    assert talk(emu, b"?", 30.0).startswith(b"<Idle|MPos:-1.000,-1.000,-1.000|")


def test_reset_while_homing_is_alarm_6():
    emu = GrblEmulator(GrblConfig(settings=((22, 1),)))
    emu.pop_output(0.0)
    talk(emu, b"$H\n", 0.1)
    assert talk(emu, b"\x18", 0.5) == b"ALARM:6\r\n"
    assert run(emu, 0.5, 1.1) == b"ok\r\n" + BANNER + b"[MSG:'$H'|'$X' to unlock]\r\n"


def test_work_positions_and_offsets():
    emu = fresh(GrblConfig(settings=((10, 0),)))
    talk(emu, b"G10 L20 P1 X2 Y3\n", 0.0)
    assert talk(emu, b"?", 0.0) == b"<Idle|WPos:2.000,3.000,0.000|FS:0,0|WCO:-2.000,-3.000,0.000>\r\n"
    talk(emu, b"G0 X-1\n", 0.0)                      # work x -1 = machine x -3
    run(emu, 0.0, 5.0)
    assert talk(emu, b"?", 5.0) == b"<Idle|WPos:-1.000,3.000,0.000|FS:0,0|Ov:100,100,100>\r\n"
    assert emu.machine.pos == (-3.0, 0.0, 0.0)


def test_jog_and_jog_cancel():
    emu = fresh()
    assert talk(emu, b"$J=G91 X-5 F600\n", 0.0) == b"ok\r\n"
    assert talk(emu, b"?", 0.3).startswith(b"<Jog|MPos:-2.500,")
    assert talk(emu, b"G0 X0\n", 0.3) == b"error:9\r\n"
    talk(emu, b"\x85", 0.3)
    assert talk(emu, b"?", 0.35).startswith(b"<Jog|")             # decelerating
    run(emu, 0.35, 0.5)
    assert talk(emu, b"?", 0.5).startswith(b"<Idle|MPos:-3.000,")
    assert talk(emu, b"G0 X0\n", 0.5) == b"ok\r\n"


def test_reply_faults_drop_garble_truncate_delay():
    emu = fresh(faults=(Fault("drop", reply="ok", nth=2), Fault("garble", reply="ok", nth=3),
                        Fault("truncate", reply="status", nth=1),
                        Fault("delay", reply="status", nth=2, delay_s=0.5)))
    assert talk(emu, b"G0 X-1\n", 0.0) == b"ok\r\n"
    assert talk(emu, b"G0 X-2\n", 0.0) == b""
    garbled = talk(emu, b"G0 X-3\n", 0.0)
    assert len(garbled) == 4 and garbled.endswith(b"\r\n") and max(garbled) >= 0x80
    cut = talk(emu, b"?", 0.0)  # cut short, no line end
    assert cut.startswith(b"<Run|MPos:") and b"\n" not in cut and len(cut) < 35
    assert talk(emu, b"?", 1.0) == b""
    assert talk(emu, b"G0 X-4\n", 1.2) == b""  # held behind the delayed report
    late = emu.pop_output(1.5)
    assert late.startswith(b"<Idle|") and late.endswith(b">\r\nok\r\n")


def test_random_faults_are_reproducible_from_the_seed():
    def replies(seed):
        emu = fresh(faults=(Fault("garble", reply="ok", nth=None, p=0.3),), seed=seed)
        return b"".join(talk(emu, b"G0 X0\n", 0.0) for _ in range(40))
    assert replies(1) == replies(1) and replies(1) != replies(2)
    assert 5 < sum(line != b"ok" for line in replies(1).split(b"\r\n")[:-1]) < 25


def test_hard_limit_fault_is_critical_like_the_firmware():
    emu = fresh(faults=(Fault("alarm", code=1, x_mm=-5.0),))
    talk(emu, b"G1 X-10 F600\nG4 P0\n", 0.0)
    assert run(emu, 0.0, 0.56) == b"ALARM:1\r\n"                     # at -5 mm after 0.55 s
    assert talk(emu, b"\x18", 0.6) == b""                              # too early: discarded
    assert run(emu, 0.6, 1.1) == b"[MSG:Reset to continue]\r\n"      # 0.5 s after the alarm
    assert emu.machine.pos[0] == pytest.approx(-5.0) and emu.state == "Alarm"
    assert talk(emu, b"?", 1.1) == b"" and talk(emu, b"G0 X0\n", 1.1) == b""   # locked
    assert talk(emu, b"\x18", 1.2) == b"ok\r\n" + BANNER + b"[MSG:'$H'|'$X' to unlock]\r\n"  # G4's stale ok
    assert talk(emu, b"$X\n", 1.3) == b"[MSG:Caution: Unlocked]\r\nok\r\n"


@pytest.mark.parametrize("code, after", [(4, b""), (9, b"\r\nGrbl 1.1h ['$' for help]\r\n[MSG:'$H'|'$X' to unlock]\r\n")])
def test_other_alarm_faults_unlock_or_reset_by_themselves(code, after):
    emu = fresh(faults=(Fault("alarm", code=code, after_s=1.0),))
    talk(emu, b"?", 0.5)
    assert talk(emu, b"", 1.4) == b"" and talk(emu, b"", 1.5) == f"ALARM:{code}\r\n".encode()
    assert run(emu, 1.5, 2.1) == after
    assert talk(emu, b"$X\n", 2.2) == b"[MSG:Caution: Unlocked]\r\nok\r\n"


def test_vanish_faults():
    emu = fresh(faults=(Fault("vanish", reply="ok", nth=2),))
    talk(emu, b"G0 X-1\n", 0.0)
    assert not emu.vanished
    talk(emu, b"G0 X-2\n", 0.0)
    assert emu.vanished
