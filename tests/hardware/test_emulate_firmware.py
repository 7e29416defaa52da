"""`feeler emulate firmware EXE`: the real Grbl 1.1h firmware (grbl-sim) served on a pty for
`feeler acquire --stage`, without socat (README, "The real firmware"). Nothing told a lab
user how to run acquire against it (an outside walk-through)."""
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from grbl_firmware import firmware_exe

from feeler.cli import main
from feeler.hardware.stage import Stage


def _alive(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().split()[2] != "Z"
    except FileNotFoundError:
        return False


def _children(pid: int) -> list[int]:
    try:
        return [int(c) for c in Path(f"/proc/{pid}/task/{pid}/children").read_text().split()]
    except FileNotFoundError:
        return []


def test_emulate_firmware_serves_grbl_on_a_pty_until_sigterm(tmp_path):
    exe = firmware_exe()
    cmd = [sys.executable, "-m", "feeler", "emulate", "firmware", str(exe), "--workdir", str(tmp_path / "fw")]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        path = proc.stdout.readline().strip()
        assert path.startswith("/dev/pts/"), proc.stderr.read() if proc.poll() is not None else path
        children = _children(proc.pid)
        assert children and all(_alive(c) for c in children)
        with Stage.open(path, reply_timeout_s=5.0) as stage:         # the real firmware answers
            assert stage.status().state == "Idle" and dict(stage.status().extra)["Pn"] == "PXYZRHS"
            assert stage.settings[110] == 500.0                         # Grbl's defaults in a fresh directory
        assert (tmp_path / "fw").is_dir()
    finally:
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=30)
    assert proc.returncode == 0 and f"feeler: Grbl 1.1h firmware (grbl-sim) on {path}; Ctrl-C to stop" in err
    deadline = time.monotonic() + 10
    while any(_alive(c) for c in children) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not any(_alive(c) for c in children), "grbl_sim.exe outlived `feeler emulate firmware`"


def test_emulate_firmware_refuses_what_is_not_the_program(tmp_path, capsys):
    assert main(["emulate", "firmware", str(tmp_path / "grbl_sim.exe")]) == 2
    assert "bash ../shared/grbl-sim/build.sh DIR" in capsys.readouterr().err


@pytest.mark.parametrize("flag", ["--help"])
def test_emulate_help_names_the_firmware(flag, capsys):
    with pytest.raises(SystemExit):
        main(["emulate", flag])
    assert "feeler emulate firmware" in capsys.readouterr().out
