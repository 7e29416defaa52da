"""The emulator held to the real Grbl 1.1h firmware: every recorded exchange replayed.

``data/grbl-1.1h-exchanges.json`` was recorded byte for byte from grbl-sim (the unchanged
firmware; ``record_firmware.py``), and ``test_firmware_live.py`` checks that the live
firmware still answers so. Here a fresh emulator gets the same bytes on a virtual clock
and must answer the same bytes, except: numbers in status reports during motion (the
firmware's own timing), the simulator's ``Pn:PXYZRHS`` (its pins all read active), and
the exchanges in ``LEFT_OUT`` (what grbl-sim cannot show of a real board).
"""
import pytest
from firmware_exchanges import EXCHANGES, LEFT_OUT, comparable, replay_on_emulator
from record_firmware import load_fixture

from feeler.hardware.emulators import GrblConfig, GrblEmulator

FIXTURE = load_fixture()
COMPARED = [name for name in EXCHANGES if name not in LEFT_OUT]


def test_fixture_is_the_recording_of_these_exchanges():
    """The recording holds exactly the steps defined here (re-record after changing them)."""
    assert list(FIXTURE["exchanges"]) == list(EXCHANGES)
    for name, steps in EXCHANGES.items():
        assert [s for s, _, _ in FIXTURE["exchanges"][name]] == [step["send"] for step in steps], name


@pytest.mark.parametrize("name", COMPARED)
def test_emulator_answers_like_the_firmware(name):
    steps = EXCHANGES[name]
    got = replay_on_emulator(GrblEmulator(GrblConfig()), steps)
    for i, (step, (sent, real, _), mine) in enumerate(zip(steps, FIXTURE["exchanges"][name], got)):
        assert comparable(mine, step["mask"]) == comparable(real, step["mask"]), \
            f"{name} step {i}: sent {sent!r}: firmware {real!r}, emulator {mine!r}"


def test_power_up_locked_with_homing_enabled():
    emu = GrblEmulator(GrblConfig(settings=((22, 1),)))
    assert emu.pop_output(0.0) == FIXTURE["power_up_locked"]
    emu.receive(b"?", 0.1)
    assert emu.pop_output(0.1).startswith(b"<Alarm|MPos:0.000,0.000,0.000|")
