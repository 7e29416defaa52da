"""The recording is the firmware: the live Grbl 1.1h (grbl-sim) still answers as recorded.

``data/grbl-1.1h-exchanges.json`` (what ``test_emulator_replay.py`` holds the emulator to)
is played again on the real firmware and must come back the same, byte for byte except the
numbers of status reports during motion (the firmware's timing on this host). By default
the exchanges without long motion; ``FEELER_FULL=1`` plays them all.
"""
import os

import pytest
from firmware_exchanges import EXCHANGES, comparable, record
from grbl_firmware import read_until
from record_firmware import load_fixture

FIXTURE = load_fixture()
QUICK = ("system commands", "g-code answers", "spindle, offsets and reports", "soft limits and critical alarms")
NAMES = list(EXCHANGES) if os.environ.get("FEELER_FULL") == "1" else list(QUICK)


@pytest.mark.parametrize("name", NAMES)
def test_the_firmware_answers_as_recorded(firmware, name):
    steps = EXCHANGES[name]
    live = record(firmware.fd, steps)
    for i, (step, (sent, recorded, _), got) in enumerate(zip(steps, FIXTURE["exchanges"][name], live)):
        assert comparable(got, step["mask"]) == comparable(recorded, step["mask"]), \
            f"{name} step {i}: sent {sent!r}: recorded {recorded!r}, live {got!r}"


def test_power_up_with_homing_enabled_is_locked(firmware):
    os.write(firmware.fd, b"$22=1\n")
    assert read_until(firmware.fd, lambda d: d.endswith(b"ok\r\n"), 60) == b"ok\r\n"
    firmware.power_cycle()                                   # the next prepare() restores $22=0
    assert firmware.boot == FIXTURE["power_up_locked"]
