"""Record :data:`firmware_exchanges.EXCHANGES` from the real Grbl 1.1h firmware (grbl-sim).

    .venv/bin/python tests/hardware/record_firmware.py      # rewrites data/grbl-1.1h-exchanges.json

Each exchange runs on the firmware after :meth:`Firmware.prepare` (back at machine zero,
then ``$RST=*``, ``$X``, Ctrl-X: Grbl's default settings, idle, report counters at zero). The file keeps, per
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

from firmware_exchanges import EXCHANGES, record  # noqa: E402
from grbl_firmware import Firmware, read_until  # noqa: E402

__all__ = ["FIXTURE", "power_up_locked", "load_fixture"]

FIXTURE = Path(__file__).parent / "data" / "grbl-1.1h-exchanges.json"


def power_up_locked(workdir: Path) -> bytes:
    """Boot output of a firmware whose EEPROM has ``$22=1`` (set, then power-cycled)."""
    with Firmware(workdir) as fw:
        os.write(fw.fd, b"$22=1\n")
        read_until(fw.fd, lambda d: d.endswith(b"ok\r\n"), 30)
        fw.power_cycle()
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
            fd = fw.fd
            for name, steps in EXCHANGES.items():
                fw.prepare()
                start = time.monotonic()
                replies, seconds = [], []
                for step in steps:
                    t0 = time.monotonic()
                    replies += record(fd, [step])
                    seconds.append(round(time.monotonic() - t0, 3))
                print(f"{name}: {len(steps)} steps in {time.monotonic() - start:.1f} s", file=sys.stderr)
                out["exchanges"][name] = [{"send": s["send"].decode("latin-1"), "reply": r.decode("latin-1"),
                                           "seconds": t} for s, r, t in zip(steps, replies, seconds)]
    FIXTURE.write_text(json.dumps(out, indent=1) + "\n", encoding="utf-8")
    print(f"wrote {FIXTURE}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
