"""Record :data:`firmware_exchanges.EXCHANGES` from the real Grbl 1.1h firmware (grbl-sim).

    .venv/bin/python tests/hardware/record_firmware.py      # rewrites data/grbl-1.1h-exchanges.json

Each exchange runs on the firmware after :func:`prepare` (back at machine zero, then
``$RST=*``, ``$X``, Ctrl-X: Grbl's default settings, idle, report counters at zero). The file keeps, per
step, the bytes sent and the bytes received, exactly (latin-1 text in JSON), and the
seconds the reply took; ``power_up_locked`` is what the firmware sends at power-up with
``$22=1`` (homing enabled: it boots locked in Alarm). ``test_firmware_live.py`` checks that
the live firmware still answers as recorded; ``test_emulator_replay.py`` holds the emulator
to the recording.
"""
from __future__ import annotations

import json
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))

from firmware_exchanges import EXCHANGES, RESET, record  # noqa: E402
from grbl_firmware import Firmware, read_until  # noqa: E402

__all__ = ["FIXTURE", "prepare", "power_up_locked", "load_fixture"]

FIXTURE = Path(__file__).parent / "data" / "grbl-1.1h-exchanges.json"
BANNER_END = b"['$' for help]\r\n"


def prepare(fd: int, timeout_s: float = 60.0) -> None:
    """Back at machine zero, Grbl's defaults, idle, report counters at zero; replies dropped."""
    home = [(b"$%d=%d\n" % (n, v), b"ok\r\n") for n, v in ((110, 3000), (111, 3000), (112, 3000),
                                                          (120, 1000), (121, 1000), (122, 1000))]
    home += [(b"G53 G0 X0 Y0 Z0\n", b"ok\r\n"), (b"G4 P0\n", b"ok\r\n")]
    wipe = [(b"$RST=*\n", BANNER_END), (b"$X\n", b"ok\r\n")]
    for send, end in [(RESET, BANNER_END), *wipe, *home, *wipe, (RESET, BANNER_END)]:
        os.write(fd, send)
        got = read_until(fd, lambda d: d.endswith(end) or d.endswith(end + b"[MSG:'$H'|'$X' to unlock]\r\n"),
                         timeout_s)
        if end not in got:
            raise RuntimeError(f"no {end!r} after {send!r}: {got!r}")
    read_until(fd, lambda d: False, 0.3)


def power_up_locked(workdir: Path) -> bytes:
    """Boot output of a firmware whose EEPROM has ``$22=1`` (set, then power-cycled)."""
    with Firmware(workdir) as fw:
        fd = os.open(fw.path, os.O_RDWR | os.O_NOCTTY)
        os.write(fd, b"$22=1\n")
        read_until(fd, lambda d: d.endswith(b"ok\r\n"), 30)
        os.close(fd)
    with Firmware(workdir) as fw:
        return fw.boot


def load_fixture(path: Path = FIXTURE) -> dict:
    """The recording, bytes restored: ``{"exchanges": {name: [(send, reply, seconds)]}, ...}``."""
    raw = json.loads(path.read_text(encoding="utf-8"))
    return {"firmware": raw["firmware"], "power_up_locked": raw["power_up_locked"].encode("latin-1"),
            "exchanges": {name: [(s["send"].encode("latin-1"), s["reply"].encode("latin-1"), s["seconds"])
                                 for s in steps] for name, steps in raw["exchanges"].items()}}


def main() -> int:
    out = {"firmware": "Grbl 1.1h (gnea/grbl bfb67f0c) in grbl-sim 9bdd1654, ../shared/grbl-sim",
           "exchanges": {}}
    with tempfile.TemporaryDirectory() as tmp:
        out["power_up_locked"] = power_up_locked(Path(tmp) / "locked").decode("latin-1")
        with Firmware(Path(tmp) / "fw") as fw:
            fd = os.open(fw.path, os.O_RDWR | os.O_NOCTTY)
            for name, steps in EXCHANGES.items():
                prepare(fd)
                start = time.monotonic()
                replies, seconds = [], []
                for step in steps:
                    t0 = time.monotonic()
                    replies += record(fd, [step])
                    seconds.append(round(time.monotonic() - t0, 3))
                print(f"{name}: {len(steps)} steps in {time.monotonic() - start:.1f} s", file=sys.stderr)
                out["exchanges"][name] = [{"send": s["send"].decode("latin-1"), "reply": r.decode("latin-1"),
                                           "seconds": t} for s, r, t in zip(steps, replies, seconds)]
            os.close(fd)
    FIXTURE.write_text(json.dumps(out, indent=1) + "\n", encoding="utf-8")
    print(f"wrote {FIXTURE}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
