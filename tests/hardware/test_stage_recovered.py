"""Damaged or lost replies the stage driver recovers from are counted (``stage.recovered``)
and reach a campaign's ``summary.json`` as bad lines."""
import json
from pathlib import Path

import pytest

from feeler.cli import main
from feeler.hardware.emulators import Fault, GrblConfig, emulator_process
from feeler.hardware.stage import ProtocolError, Stage, StageTimeout
from feeler.hardware.stage.protocol import damage_of

FAST = GrblConfig(max_rate_mm_min=(60000.0,) * 3, accel_mm_s2=(20000.0,) * 3, start_mm=(0.0, 0.0, -20.0))
TINY = Path(__file__).parent / "data" / "tiny-plan.toml"


def test_damage_of_each_kind_and_a_real_error_is_no_damage():
    assert damage_of(ProtocolError(None, b"<Id#e|")) == "malformed"
    assert damage_of(StageTimeout("status report", 0.3, b"<Idle|MP")) == "short_read"
    assert damage_of(StageTimeout("status report", 0.3)) == "lost"
    assert damage_of(ProtocolError(20, b"error:20")) is None
    assert damage_of(ValueError("x")) is None


@pytest.mark.parametrize("fault, counted", [
    (None, {}),
    (Fault("drop", reply="ok", nth=4), {"ok_lost": 1}),            # open used ok #1 ($$), #2 ($I), #3 (G21 G90)
    (Fault("garble", reply="ok", nth=4), {"ok_malformed": 1}),
    (Fault("truncate", reply="ok", nth=4), {"ok_short_read": 1}),
    (Fault("drop", reply="status", nth=2), {"status_lost": 1}),    # open read status #1
    (Fault("garble", reply="status", nth=2), {"status_malformed": 1}),
    (Fault("truncate", reply="status", nth=2), {"status_short_read": 1}),
    (Fault("delay", reply="status", nth=2, delay_s=1.5), {"status_lost": 1}),
], ids=["none", "dropped ok", "garbled ok", "truncated ok", "dropped status", "garbled status",
        "truncated status", "late status"])
def test_each_recovered_reply_is_counted_once(fault, counted):
    # a reply timeout of 1 s: long enough that a loaded host never makes an honest reply
    # late (exact counts), short enough that the injected losses cost little time
    with emulator_process(FAST, faults=() if fault is None else (fault,)) as emu, \
            Stage.open(emu.path, reply_timeout_s=1.0, poll_s=0.005) as stage:
        stage.move_to(x_mm=-7.0, feed_mm_min=30000.0)
        assert stage.wait_idle().mpos_mm == (-7.0, 0.0, -20.0)
        for _ in range(3):
            assert stage.position_mm() == (-7.0, 0.0, -20.0)
        assert stage.recovered == counted
        with pytest.raises(ProtocolError):
            stage.protocol.send("G4 P-1")                          # error:4 is an answer, not damage
        assert stage.recovered == counted


def test_driver_recoveries_are_bad_lines_in_the_campaign_summary(tmp_path, capsys):
    plan = tmp_path / "one.toml"
    plan.write_text(TINY.read_text().replace("heights_mm = [0.0, 0.2]", "heights_mm = [0.0]")
                    .replace("origin_x_mm = [-20.0, -16.0]", "origin_x_mm = [-20.0]")
                    .replace("scans_per_plate = 2", "scans_per_plate = 1"))
    run = tmp_path / "run"
    faults = ["garble:reply=ok,nth=5", "garble:reply=status,nth=6", "truncate:reply=status,nth=12"]
    assert main(["acquire", "--emulate", "--plan", str(plan), "--out", str(run)]
                + [a for f in faults for a in ("--fault", f)]) == 0
    assert "1 of 1 scans (complete)" in capsys.readouterr().out
    summary = json.loads((run / "summary.json").read_text())
    assert summary["complete"] and summary["bad_lines"] == 3 and summary["bad_frames"] == 0
    events = [json.loads(ln) for ln in (run / "journal.jsonl").read_text().splitlines()]
    reasons = sorted(e["reason"] for e in events if e["event"] == "bad_line")
    assert reasons == [f"recovered by the driver: {k}" for k in ("ok_malformed", "status_malformed",
                                                                  "status_short_read")]
