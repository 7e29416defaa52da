"""Ports that cannot be opened, each a one-line error naming the port; the emulate CLI."""
import os
import subprocess
import sys
import tempfile

import pytest

from feeler.cli import main
from feeler.hardware.emulators import GrblConfig, emulator_process
from feeler.hardware.stage import PortError, Stage
from feeler.hardware.stage.transport import open_port


def one_line(exc) -> str:
    text = str(exc)
    assert "\n" not in text
    return text


def test_port_that_does_not_exist(tmp_path):
    path = str(tmp_path / "ttyUSB9")
    with pytest.raises(PortError) as info:
        Stage.open(path)
    assert one_line(info.value).startswith(f"port {path}: does not exist")


def test_busy_port_is_refused_with_an_exclusive_lock():
    with emulator_process(GrblConfig()) as emu:
        first = open_port(emu.path)
        try:
            with pytest.raises(PortError) as info:
                Stage.open(emu.path)
            assert one_line(info.value) == (f"port {emu.path}: busy: another program holds it open "
                                            "(exclusive lock refused)")
        finally:
            first.close()
        Stage.open(emu.path, reply_timeout_s=1.0).close()  # free again once closed


def open_as_unprivileged(path: str) -> str:
    """The error text of ``open_port(path)`` without root's right to ignore file modes.

    As root, the effective uid is 'nobody' (65534) for the duration of the call only (the
    saved uid stays 0, so it is restored); no fork, so safe in a threaded process.
    """
    root = os.geteuid() == 0
    if root:
        os.seteuid(65534)
    try:
        open_port(path)
        return "opened"
    except Exception as exc:
        return f"{type(exc).__name__} {exc}"
    finally:
        if root:
            os.seteuid(0)


def test_permission_denied():
    with tempfile.TemporaryDirectory() as folder:
        os.chmod(folder, 0o755)  # reachable by anyone: only the device's mode 000 refuses
        device = os.path.join(folder, "ttyACM0")
        open(device, "w").close()
        os.chmod(device, 0o000)
        assert open_as_unprivileged(device) == (
            f"PortError port {device}: permission denied (join the 'dialout' group or fix the device mode)")


def test_not_a_serial_device_and_bad_url(tmp_path):
    plain = tmp_path / "notes.txt"
    plain.write_text("not a tty")
    with pytest.raises(PortError, match=f"port {plain}: not a serial device"):
        open_port(str(plain))
    with pytest.raises(PortError, match="port nosuch://x: not a device path or pyserial URL"):
        open_port("nosuch://x")


def test_emulate_stage_command_serves_until_sigterm():
    proc = subprocess.Popen([sys.executable, "-m", "feeler", "emulate", "stage", "--start-mm", "-5", "-6", "-7",
                             "--max-rate-mm-min", "60000", "60000", "3000", "--setting", "10=0"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        path = proc.stdout.readline().strip()
        assert path.startswith("/dev/")
        with Stage.open(path, reply_timeout_s=1.0) as stage:
            assert stage.position_mm() == (-5.0, -6.0, -7.0)            # from WPos + WCO ($10=0)
            assert stage.limits.max_rate_mm_min == (60000.0, 60000.0, 3000.0)
    finally:
        proc.terminate()
        assert proc.wait(10) == 0


@pytest.mark.parametrize("args, message", [
    (["--fault", "melt"], "argument --fault='melt': fault one of delay, drop"),
    (["--fault", "drop:nth=0"], "argument --fault='drop:nth=0': fault nth an integer >= 1 or none"),
    (["--fault", "alarm:code=1"], "an alarm needs after_s or one of x_mm, y_mm, z_mm"),
    (["--travel-mm", "0", "1", "1"], "argument --travel-mm=[0.0, 1.0, 1.0]: three numbers > 0"),
    (["--setting", "22"], "argument --setting='22': N=VALUE, e.g. 22=1"),
    (["--setting", "99=1"], "argument --setting='99=1': a Grbl 1.1h setting (0, 1,"),
])
def test_emulate_stage_rejects_bad_options(args, message, capsys):
    assert main(["emulate", "stage", *args]) == 2
    out, err = capsys.readouterr()
    said = [ln for ln in err.splitlines() if ln.startswith("feeler: ")]       # beside the first status line
    assert out == "" and len(said) == 1 and said[0].startswith("feeler: error: ") and message in said[0]
