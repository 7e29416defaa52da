"""Damaged or lost replies the stage driver recovers from are counted (``stage.recovered``)
and reach a campaign's ``summary.json`` as bad lines."""
import json
import logging
from pathlib import Path

import pytest

from feeler.cli import main
from feeler.errors import ArgumentError
from feeler.hardware.emulators import Fault, GrblConfig, emulator_process
from feeler.hardware.stage import ProtocolError, Stage, StageTimeout
from feeler.hardware.stage.protocol import damage_of
from feeler.hardware.stage.replies import Message

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


@pytest.mark.parametrize("fault, line", [
    (Fault("drop", reply="ok", nth=1), "$$"), (Fault("drop", reply="ok", nth=2), "$I"),
    (Fault("drop", reply="ok", nth=3), "G21 G90"), (Fault("garble", reply="ok", nth=1), "$$"),
    (Fault("truncate", reply="ok", nth=3), "G21 G90"), (Fault("garble", reply="setting", nth=5), "$$"),
    (Fault("lose", nth=2), "$I"),
], ids=["dropped $$ ok", "dropped $I ok", "dropped G21 G90 ok", "garbled $$ ok", "truncated G21 G90 ok",
        "garbled setting", "lost $I line"])
def test_a_set_up_line_whose_reply_was_lost_is_asked_again(fault, line, caplog):
    """Opening sends $$, $I and G21 G90, each safe to repeat: a lost or damaged reply to one of
    them failed the open (and `acquire` exited 1, writing nothing: an outside walk-through,
    with the `feeler emulate --help` example drop:reply=ok,nth=3). Now it is sent again,
    counted as the lost reply to a move is, and the settings read are the board's."""
    with caplog.at_level(logging.WARNING, logger="feeler.hardware.stage"), \
            emulator_process(FAST, faults=(fault,)) as emu, Stage.open(emu.path, reply_timeout_s=0.3) as stage:
        assert f"{line!r} is safe to repeat: sending it again (try 2 of 3)" in caplog.text
        assert stage.recovered == {f"ok_{damage_of_fault(fault)}": 1}
        assert stage.settings[110] == 60000.0 and stage.limits.max_rate_mm_min == (60000.0,) * 3
        assert stage.protocol.rx_buffer_bytes == 128
        modes = [r.text for r in stage.protocol.send("$G") if isinstance(r, Message)][0].split()
        assert "G21" in modes and "G90" in modes
        stage.move_to(x_mm=-7.0, feed_mm_min=30000.0)
        assert stage.wait_idle().mpos_mm == (-7.0, 0.0, -20.0)


def damage_of_fault(fault: Fault) -> str:
    return {"drop": "lost", "lose": "lost", "garble": "malformed", "truncate": "short_read"}[fault.kind]


def test_a_set_up_reply_lost_every_time_still_fails_after_three_tries():
    with emulator_process(FAST, faults=(Fault("drop", reply="ok", nth=None),)) as emu:
        with pytest.raises(StageTimeout, match=r"no reply to '\$\$' \(controller Idle\)"):
            Stage.open(emu.path, reply_timeout_s=0.2)


def test_only_lines_safe_to_repeat_are_asked_again():
    from feeler.hardware.stage.commands import idempotent

    for line in ("$$", "$I", "$G", "$#", "$X", "G21 G90", "G90", "g21  g90", "G17 G21 G90 G94"):
        assert idempotent(line), line
    for line in ("G53 G1 X-1 F100", "G91", "G4 P1", "$H", "$110=500", "$RST=*", "G21 G90 X1", "G92 X0",
                 "M3 S100", "", "G210", "G21.1"):
        assert idempotent(line) == (line == "G91"), line
    with emulator_process(FAST) as emu, Stage.open(emu.path, reply_timeout_s=0.3) as stage:
        with pytest.raises(ArgumentError, match="safe to send twice"):
            stage.protocol.ask("G53 G1 X-1 F100")


def test_acquire_with_the_emulate_help_example_fault_completes(tmp_path, capsys, caplog):
    """`feeler emulate --help`'s example, --fault drop:reply=ok,nth=3, loses the reply to the
    third set-up line (G21 G90): the campaign ran nothing and exited 1. It now completes, and
    the journal holds the lost reply as a bad line of no scan (it happened while opening)."""
    plan = tmp_path / "one.toml"
    plan.write_text(TINY.read_text().replace("heights_mm = [0.0, 0.2]", "heights_mm = [0.0]")
                    .replace("origin_x_mm = [-20.0, -16.0]", "origin_x_mm = [-20.0]")
                    .replace("scans_per_plate = 2", "scans_per_plate = 1"))
    run = tmp_path / "run"
    with caplog.at_level(logging.WARNING, logger="feeler.hardware.stage"):
        assert main(["acquire", "--emulate", "--plan", str(plan), "--out", str(run), "--no-progress",
                     "--fault", "drop:reply=ok,nth=3"]) == 0
    assert "1 of 1 scans (complete)" in capsys.readouterr().out
    assert "'G21 G90' is safe to repeat: sending it again" in caplog.text
    events = [json.loads(ln) for ln in (run / "journal.jsonl").read_text().splitlines()]
    bad = [e for e in events if e["event"] == "bad_line"]
    assert [(e["scan_id"], e["reason"]) for e in bad] == [(None, "recovered by the driver: ok_lost")]
    assert json.loads((run / "summary.json").read_text())["bad_lines"] == 1
