"""Grbl reply parser: exact lines from the Grbl 1.1 interface docs, bad lines, random bytes."""
import pytest
from hypothesis import given, settings, strategies as st

from feeler.errors import FeelerError, InputError
from feeler.hardware.stage.errors import (GRBL_ALARMS, GRBL_ERRORS, PortError, ProtocolError,
                                          StageAlarm, StageDisconnected, StageTimeout)
from feeler.hardware.stage.replies import (Alarm, Banner, Error, Message, Ok, Setting, Status,
                                           parse_reply)

GOOD = [
    (b"ok", Ok()),
    (b"error:22", Error(22)),
    (b"ALARM:2", Alarm(2)),
    (b"<Idle|MPos:0.000,0.000,0.000|FS:0,0>",
     Status("Idle", None, (0.0, 0.0, 0.0), None, 0.0, 0.0)),
    (b"<Hold:1|MPos:10.125,-2.500,3.000|FS:500,0|WCO:0.000,0.000,0.000>",
     Status("Hold", 1, (10.125, -2.5, 3.0), None, 500.0, 0.0, (("WCO", "0.000,0.000,0.000"),))),
    (b"<Run|WPos:1.000,2.000,3.000|Bf:15,128|F:250>",
     Status("Run", None, None, (1.0, 2.0, 3.0), 250.0, 0.0, (("Bf", "15,128"),))),
    (b"<Door:2|MPos:0.000,0.000,0.000|FS:0,12000|Pn:XZ|Ov:100,100,100>",
     Status("Door", 2, (0.0, 0.0, 0.0), None, 0.0, 12000.0, (("Pn", "XZ"), ("Ov", "100,100,100")))),
    (b"[MSG:Caution: Unlocked]", Message("MSG", "Caution: Unlocked")),
    (b"[GC:G0 G54 G17 G21 G90 G94 M5 M9 T0 F0 S0]", Message("GC", "G0 G54 G17 G21 G90 G94 M5 M9 T0 F0 S0")),
    (b"[MSG:'$H'|'$X' to unlock]", Message("MSG", "'$H'|'$X' to unlock")),
    (b"$110=500.000", Setting(110, 500.0)),
    (b"$0=10", Setting(0, 10.0)),
    (b"Grbl 1.1h ['$' for help]", Banner("1.1h")),
]

BAD = [
    b"", b"OK", b"ok ", b"o\xebk", b"error:", b"error:x", b"error:1234", b"ALARM:",
    b"<Idle|MPo", b"<Idle|MPos:1,2|FS:0,0>", b"<Idle|FS:0,0>", b"<Walk|MPos:0,0,0>",
    b"<Idle|MPos:0.000,0.000,0.000|FS:0>", b"<Idle|MPos:0,0,0|MPos:0,0,0>",
    b"<Idle|MPos:0,0,0|FS:a,b>", b"<Idle|MPos:0,0,0|F:1,2>", b"[MSG:unterminated", b"$x=1",
    b"Grbl 1.1h", b"<Idle|MPos:0,0,0||FS:0,0>", b"<Idle|MPos:1e5,0,0>",
]


@pytest.mark.parametrize("line, reply", GOOD, ids=[g[0].decode()[:30] for g in GOOD])
def test_parse_reply_exact(line, reply):
    assert parse_reply(line) == reply


@pytest.mark.parametrize("line", BAD, ids=[repr(b)[:30] for b in BAD])
def test_malformed_reply_is_protocol_error_without_code(line):
    with pytest.raises(ProtocolError) as info:
        parse_reply(line)
    assert info.value.code is None and info.value.line == line
    assert "\n" not in str(info.value)


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=80) | st.text("okerrorALRM:<>|IdleRunHoldMPosFS,.0123456789-$=[]").map(str.encode))
def test_random_bytes_give_a_reply_or_a_typed_error(line):
    try:
        reply = parse_reply(line)
    except ProtocolError as exc:
        assert exc.code is None
    else:
        assert isinstance(reply, (Ok, Error, Alarm, Status, Message, Setting, Banner))


def test_code_tables_and_messages():
    assert GRBL_ERRORS[22] == "undefined feed rate" and GRBL_ALARMS[2].startswith("soft limit")
    assert str(StageAlarm(2)) == "ALARM:2 (soft limit: motion target exceeds machine travel; position retained)"
    assert str(ProtocolError(22, b"error:22", "G1 X1")) == "error:22 to 'G1 X1' (undefined feed rate)"
    assert StageAlarm(99).meaning == "unknown alarm code"
    assert "short read b'<Idle'" in str(StageTimeout("status", 0.5, b"<Idle"))
    assert str(StageTimeout("status", 0.5)) == "no status within 0.5 s"
    assert isinstance(StageDisconnected("/dev/x", "gone"), FeelerError)
    assert isinstance(PortError("/dev/x", "busy"), InputError)
    assert str(PortError("/dev/x", "busy")) == "port /dev/x: busy"
