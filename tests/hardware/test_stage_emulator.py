"""The Grbl emulator's state machine on a virtual clock: bytes in -> bytes out, exactly."""
import pytest

from feeler.hardware.emulators import Fault, GrblConfig, GrblEmulator

BANNER = b"\r\nGrbl 1.1h ['$' for help]\r\n"
# 10 mm/s along x with 100 mm/s^2: 0.1 s ramps, 0.9 s cruise for 10 mm
SLOW = GrblConfig(max_rate_mm_min=(6000.0, 600.0, 6000.0), accel_mm_s2=(100.0, 100.0, 100.0))


def talk(emu, data: bytes, now: float) -> bytes:
    emu.receive(data, now)
    emu.tick(now)
    return emu.pop_output(now)


def status(emu, now):
    text = talk(emu, b"?", now).decode()
    return text.split("|")[0][1:], text.split("|")[1], text.split("|")[2].split(">")[0]


def fresh(config=SLOW, faults=(), seed=0):
    emu = GrblEmulator(config, faults, seed)
    assert emu.pop_output(0.0) == BANNER
    return emu


@pytest.mark.parametrize("line, code", [
    (b"G1 X1", 22), (b"G1 X1 F0", 22), (b"G2 X1 F100", 20), (b"G0 G1 X1", 21), (b"X1 X2", 25),
    (b"G4", 28), (b"G1 X1 F-5", 4), (b"G4 P-1", 4), (b"1X", 1), (b"G1 X", 2), (b"G90 P1", 36),
    (b"Q1", 20), (b"G1.5 X1", 20), (b"M3", 20), (b"N-1 G0 X1", 27), (b"G4 P1 X1", 31),
    (b"G0 X" + b"1" * 80, 11), (b"$Y", 3), (b"$110=abc", 2), (b"$110=-1", 4), (b"$999=1", 3),
    (b"$J=G91 X1 F10", 3),
])
def test_bad_lines_answer_grbls_error_code(line, code):
    emu = fresh()
    assert talk(emu, line + b"\n", 0.0) == f"error:{code}\r\n".encode()
    assert emu.pos == (0.0, 0.0, 0.0)


def test_trapezoidal_move_reported_in_real_time():
    emu = fresh()
    assert talk(emu, b"G1 X10 F600\n", 0.0) == b"ok\r\n"
    assert talk(emu, b"?", 0.05) == b"<Run|MPos:0.125,0.000,0.000|FS:300,0|WCO:0.000,0.000,0.000>\r\n"
    assert talk(emu, b"?", 0.6) == b"<Run|MPos:5.500,0.000,0.000|FS:600,0|Ov:100,100,100>\r\n"
    assert talk(emu, b"?", 1.05) == b"<Run|MPos:9.875,0.000,0.000|FS:300,0>\r\n"
    assert talk(emu, b"?", 1.2) == b"<Idle|MPos:10.000,0.000,0.000|FS:0,0>\r\n"


def test_rapid_is_limited_per_axis():
    emu = fresh()  # y is limited to 600 mm/min = 10 mm/s, x to 100 mm/s
    talk(emu, b"G0 X10 Y10\n", 0.0)
    # path rate limited so y moves at 10 mm/s: |u_y| = 1/sqrt(2) -> path 14.14 mm/s
    state, mpos, fs = status(emu, 0.5)
    assert state == "Run" and fs == "FS:849,0"
    assert emu.pos[0] == pytest.approx(emu.pos[1])


def test_feed_hold_decelerates_and_cycle_start_resumes():
    emu = fresh()
    talk(emu, b"G1 X10 F600\n", 0.0)
    talk(emu, b"!", 0.6)  # at 5.5 mm, 10 mm/s: stops 0.5 mm later after 0.1 s
    assert status(emu, 0.65)[0] == "Hold:1"
    assert status(emu, 0.8) == ("Hold:0", "MPos:6.000,0.000,0.000", "FS:0,0")
    talk(emu, b"~", 1.0)
    assert status(emu, 1.05) == ("Run", "MPos:6.125,0.000,0.000", "FS:300,0")
    assert status(emu, 1.6)[0] == "Idle" and emu.pos == (10.0, 0.0, 0.0)


def test_dwell_acknowledges_after_motion_and_delay():
    emu = fresh()
    talk(emu, b"G1 X10 F600\nG4 P0.5\n", 0.0)
    assert emu.pop_output(0.0) == b""  # the first ok came with the talk above
    assert talk(emu, b"", 1.15) == b""
    emu.tick(1.2)
    assert talk(emu, b"", 1.6) == b""
    assert talk(emu, b"", 1.71) == b"ok\r\n"


def test_planner_acknowledges_fifteen_blocks_ahead():
    emu = fresh()
    assert talk(emu, b"G1F600\n", 0.0) == b"ok\r\n"
    lines = b"".join(f"X{i}\n".encode() for i in range(1, 18))  # 17 moves, 1 mm each
    assert len(lines) <= 127
    out = talk(emu, lines, 0.0)
    assert out == b"ok\r\n" * 15
    out = talk(emu, b"", 0.25)  # the first 1 mm block (0.2 s) is done: one slot frees
    assert out == b"ok\r\n"


def test_receive_buffer_overflow_loses_bytes():
    emu = fresh()
    talk(emu, b"G4 P10\n", 0.0)  # the dwell blocks line execution
    talk(emu, b"G0 X1\n" * 30, 0.1)
    assert emu.lost_bytes == 30 * 6 - 127


def test_soft_limit_is_a_critical_alarm_until_reset_and_unlock():
    emu = fresh()
    assert talk(emu, b"G0 X500\n", 0.0) == b"ALARM:2\r\n[MSG:Reset to continue]\r\n"
    assert talk(emu, b"G0 X1\n", 0.1) == b""  # ignored until reset
    assert status(emu, 0.1)[0] == "Alarm"
    assert talk(emu, b"\x18", 0.2) == BANNER + b"[MSG:'$H'|'$X' to unlock]\r\n"
    assert talk(emu, b"G0 X1\n", 0.3) == b"error:9\r\n"
    assert talk(emu, b"$X\n", 0.4) == b"[MSG:Caution: Unlocked]\r\nok\r\n"
    assert talk(emu, b"G0 X1\n", 0.5) == b"ok\r\n"


def test_reset_in_motion_is_alarm_3_and_keeps_position():
    emu = fresh()
    talk(emu, b"G1 X10 F600\n", 0.0)
    out = talk(emu, b"\x18", 0.6)
    assert out == b"ALARM:3\r\n" + BANNER + b"[MSG:'$H'|'$X' to unlock]\r\n"
    assert emu.pos == (5.5, 0.0, 0.0) and emu.state == "Alarm"


def test_system_commands():
    emu = fresh(GrblConfig(travel_mm=(100.0, 90.0, 30.0)))
    settings = talk(emu, b"$$\n", 0.0).decode().split("\r\n")
    assert settings[:2] == ["$0=10", "$1=25"] and "$130=100.000" in settings
    assert settings[-2:] == ["ok", ""]
    assert talk(emu, b"$G\n", 0.0) == b"[GC:G0 G54 G17 G21 G90 G94 M5 M9 T0 F0 S0]\r\nok\r\n"
    assert talk(emu, b"$I\n", 0.0) == b"[VER:1.1h.20190825:]\r\n[OPT:V,15,128]\r\nok\r\n"
    assert talk(emu, b"$110=1200\n", 0.0) == b"ok\r\n" and emu.settings[110] == 1200.0
    assert talk(emu, b"G91 G20 G1 X1 F100\n", 0.0) == b"ok\r\n"  # inches, relative
    assert talk(emu, b"$$\n", 0.1) == b"error:8\r\n"  # not idle
    assert status(emu, 5.0)[1] == "MPos:25.400,0.000,0.000"
    assert talk(emu, b"$H\n", 5.0) == b""
    assert talk(emu, b"", 9.0) == b"ok\r\n" and emu.pos == (0.0, 0.0, 0.0)


def test_reply_faults_drop_garble_truncate_delay():
    emu = fresh(faults=(Fault("drop", reply="ok", nth=2), Fault("garble", reply="ok", nth=3),
                        Fault("truncate", reply="status", nth=1),
                        Fault("delay", reply="status", nth=2, delay_s=0.5)))
    assert talk(emu, b"G0 X1\n", 0.0) == b"ok\r\n"
    assert talk(emu, b"G0 X2\n", 0.0) == b""
    garbled = talk(emu, b"G0 X3\n", 0.0)
    assert len(garbled) == 4 and garbled.endswith(b"\r\n") and max(garbled) >= 0x80
    cut = talk(emu, b"?", 0.0)  # cut short, no line end
    assert cut.startswith(b"<Run|MPos:") and b"\n" not in cut and len(cut) < 35
    assert talk(emu, b"?", 1.0) == b""
    assert talk(emu, b"G0 X4\n", 1.2) == b""  # held behind the delayed report
    assert emu.pop_output(1.5).startswith(b"<") and emu.pop_output(1.5) == b""


def test_random_faults_are_reproducible_from_the_seed():
    def run(seed):
        emu = fresh(faults=(Fault("garble", reply="ok", nth=None, p=0.3),), seed=seed)
        return b"".join(talk(emu, b"G0 X0\n", 0.0) for _ in range(40))
    assert run(1) == run(1) and run(1) != run(2)
    assert 5 < sum(line != b"ok" for line in run(1).split(b"\r\n")[:-1]) < 25


def test_alarm_and_vanish_faults():
    emu = fresh(faults=(Fault("alarm", code=1, x_mm=5.0),))
    talk(emu, b"G1 X10 F600\n", 0.0)
    out = b"".join(talk(emu, b"", t / 100) for t in range(1, 100))
    assert out == b"ALARM:1\r\n[MSG:Reset to continue]\r\n"
    assert emu.pos[0] == pytest.approx(5.0) and emu.state == "Alarm"
    emu = fresh(faults=(Fault("alarm", code=6, after_s=1.0),))
    talk(emu, b"?", 0.5)
    assert talk(emu, b"", 1.4) == b"" and talk(emu, b"", 1.5) == b"ALARM:6\r\n"
    assert talk(emu, b"$X\n", 1.6).endswith(b"ok\r\n")  # not critical: $X alone unlocks
    emu = fresh(faults=(Fault("vanish", reply="ok", nth=2),))
    talk(emu, b"G0 X1\n", 0.0)
    assert not emu.vanished
    talk(emu, b"G0 X2\n", 0.0)
    assert emu.vanished
