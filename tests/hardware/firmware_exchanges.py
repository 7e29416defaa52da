"""Byte-level exchanges with Grbl 1.1h, recorded from the real firmware and replayed.

Each exchange starts from a reset controller with Grbl's default settings (``$RST=*``
then Ctrl-X on the real firmware, a fresh emulator in replay) and is a list of steps:
bytes sent and the bytes that came back. :func:`record` plays them against a serial
file descriptor (the real firmware on its pty) and returns what came back;
:func:`replay_on_emulator` plays the recorded steps on a
:class:`~feeler.hardware.emulators.GrblEmulator` on a virtual clock and returns what the
emulator answered; :func:`comparable` masks what legitimately differs (positions and
feeds during motion, the simulator's pins ``Pn:PXYZRHS``) so the two can be compared byte
for byte. ``data/grbl-1.1h-exchanges.json`` holds the recording (``record_firmware.py``).

A step is a dict: ``send`` (bytes), ``until`` (the reply is complete when it ends with
these bytes; default: a line ``ok``/``error:N``; ``b""``: nothing expected), ``quiet_s``
(then read on until this long passes in silence), ``sleep_s`` (wait before sending), and
``mask`` (``"motion"``: the numbers of status reports are masked).
"""
from __future__ import annotations

import os
import re
import select
import time

__all__ = ["EXCHANGES", "RESET", "record", "replay_on_emulator", "comparable", "LEFT_OUT"]

RESET = b"\x18"
OK_OR_ERROR = re.compile(rb"(?:^|\n)(?:ok|error:\d+)\r\n$")
REPORT = b">\r\n"


def S(send: bytes, until: bytes | None = None, *, quiet_s: float = 0.05, sleep_s: float = 0.0,
      mask: str | None = None) -> dict:
    return {"send": send, "until": until, "quiet_s": quiet_s, "sleep_s": sleep_s, "mask": mask}


def Q(until: bytes = REPORT, **kw) -> dict:
    """A status query."""
    return S(b"?", until, **kw)


SOFT_LIMITS_ON = [S(b"$22=1\n"), S(b"$20=1\n"), S(b"$X\n")]
FAST = [S(b"$110=3000\n"), S(b"$111=3000\n"), S(b"$112=3000\n"), S(b"$120=1000\n"), S(b"$121=1000\n"),
        S(b"$122=1000\n")]

EXCHANGES: dict[str, list[dict]] = {
    "system commands": [
        S(b"$\n"), S(b"$$\n"), S(b"$#\n"), S(b"$G\n"), S(b"$I\n"), S(b"$N\n"),
        S(b"$Z\n"), S(b"$Y\n"), S(b"$999=1\n"), S(b"$110=abc\n"), S(b"$110=-1\n"), S(b"$104=1\n"),
        S(b"$0=2\n"), S(b"$7=1\n"), S(b"$X\n"), S(b"$H\n"), S(b"$20=1\n"), S(b"$22=1\n"), S(b"$20=1\n"),
        S(b"$$\n"), S(b"$22=0\n"), S(b"$$\n"), S(b"$x\n"), S(b"$ G\n"), S(b"$GG\n"), S(b"$J\n"),
        S(b"$J=G91 X1\n"), S(b"$J=G91 G1 X1 F10\n"), S(b"$J=G91 X1 F10 M3\n"), S(b"$J=G91 X1 F10 S1\n"),
        S(b"$RST=$\n", b"]\r\nok\r\n\r\nGrbl 1.1h ['$' for help]\r\n"), Q(), S(b"$C\n"), S(b"G0 X-5\n"),
        Q(), S(b"G4 P10\n"), S(b"$$\n"), S(b"$C\n", b"help]\r\n", quiet_s=0.3), Q(),
    ],
    "g-code answers": [
        *FAST, S(b"G0 G1 X1\n"), S(b"N-1 G0\n"), S(b"G1.5 X1\n"), S(b"G1 X-1\n"), S(b"G1 X-1 F0\n"),
        S(b"X1 X2\n"), S(b"G4\n"), S(b"G1 X-1 F-5\n"), S(b"G4 P-1\n"), S(b"1X\n"), S(b"G1 X\n"),
        S(b"G90 P1\n"), S(b"Q1\n"), S(b"G4 P0.1 X1\n"), S(b"G0 X" + b"1" * 80 + b"\n"), S(b"G17 G18\n"),
        S(b"G59.1\n"), S(b"G30.2\n"), S(b"G61.1\n"), S(b"G64\n"), S(b"G90.1\n"), S(b"G80 X1\n"),
        S(b"M7\n"), S(b"M56\n"), S(b"M3.5\n"), S(b"T256\n"), S(b"L1\n"), S(b"G0 X-1 R1\n"),
        S(b"N10000001 G0\n"), S(b"G43.1 X1\n"), S(b"G43\n"), S(b"G10 X1\n"), S(b"G10 L20 X1\n"),
        S(b"G10 L3 P1 X1\n"), S(b"G10 L2 P10 X1\n"), S(b"G92\n"), S(b"G53\n"),
        S(b"G0 G92 X1\n"), S(b"G28 G92 X1\n"), S(b"G1 G80 X1\n"), S(b"(comment) g0 x0 ; tail\n"),
        S(b"/G0 X0\n"), S(b"\n"), S(b"G20\n"), S(b"G21\n"), S(b"G91.1\n"), S(b"G61 G40 G94 G17 G90\n"),
        S(b"M1\n"), S(b"T1\n"), S(b"G54\n"), S(b"G59\n"), S(b"G54\n"), S(b"G28.1\n"), S(b"G30.1\n"),
        S(b"G49\n"), S(b"G80\n"), S(b"G0\n"), S(b"$G\n"), S(b"M2\n"), S(b"$G\n"),
    ],
    "spindle, offsets and reports": [
        Q(), Q(), S(b"M3\n"), Q(), S(b"S100\n"), Q(), S(b"M8\n"), Q(), Q(), S(b"M9 M5\n"), Q(), Q(),
        S(b"G10 L20 P1 X1\n"), Q(), Q(), S(b"G92 Y2\n"), Q(), S(b"$#\n"), S(b"G92.1\n"), Q(),
        S(b"G43.1 Z0.5\n"), Q(), S(b"$10=0\n"), Q(), S(b"$10=2\n"), Q(), S(b"$10=3\n"), Q(),
        S(b"$13=1\n"), Q(), S(b"$G\n"), S(b"$13=0\n"), S(b"$10=1\n"), S(b"G49\n"), S(b"G10 L2 P1 X0\n"),
        *[Q() for _ in range(12)], S(b"G55\n"), Q(), S(b"G54\n"), Q(),
    ],
    "moves, planner and dwell": [
        *FAST, S(b"G53 G1 X-1.001 Y-0.5 F3000\n"), S(b"G4 P0\n"), Q(), S(b"G91 G0 Z-0.25\n"),
        S(b"G4 P0\n"), Q(), S(b"G90 G20 G0 X-0.1\n"), S(b"G4 P0\n"), Q(), S(b"G21 G53 G0 X0 Y0 Z0\n"),
        S(b"G4 P0\n"), S(b"G4 P0.3\n"), S(b"G1 X0 F100\n"), S(b"G0 X0\n"), S(b"G1 F100\n"), S(b"G91\n"),
        S(b"G1 X-0.02\n" * 10, b"ok\r\n" * 10), S(b"G1 X-0.02\n" * 8, b"ok\r\n" * 8), S(b"G4 P0\n"), Q(),
        S(b"G1 X-1 F60\n"), S(b"$I\n"), S(b"$X\n"), S(b"$$\n"), S(b"$G\n"), S(b"$#\n"), S(b"$C\n"), S(b"$H\n"),
        S(b"$22=1\n"), S(b"G4 P0\n"), Q(), S(b"G90 G0 X0\n"), S(b"G4 P0\n"),
        S(b"G4 P2\n", b"", quiet_s=0.2), S(b"\x18", b"help]\r\n", quiet_s=0.3), Q(), S(b"M0\n", b"", quiet_s=0.3),
        Q(), S(b"~", quiet_s=0.1), Q(), S(b"G4 P0.2\n$G\n", b"ok\r\n", quiet_s=0.0),
    ],
    "feed hold, resume, reset in motion": [
        *FAST, S(b"$120=10\n"), S(b"G1 X-2 F60\n"), Q(sleep_s=0.3, mask="motion"), S(b"!", b"", quiet_s=0.0),
        S(b"~", b"", quiet_s=0.0), Q(sleep_s=2.0, mask="motion"), S(b"$G\n", b"", quiet_s=0.5),
        S(b"~", quiet_s=0.2), Q(mask="motion"), S(b"\x18", b"unlock]\r\n", quiet_s=0.3), Q(mask="motion"),
        S(b"$X\n"), S(b"!", b"", quiet_s=0.1), Q(mask="motion"), S(b"$G\n", b"", quiet_s=0.3),
        S(b"~", quiet_s=0.1), Q(mask="motion"),
    ],
    "jogging": [
        *FAST, S(b"$J=G91 X-2 F60\n"), Q(sleep_s=0.2, mask="motion"), S(b"G0 X0\n"), S(b"$G\n"),
        S(b"$J=G53 X-3 F60\n"), S(b"\x85", b"", quiet_s=0.0), Q(sleep_s=1.0, mask="motion"),
        S(b"$J=G91 X-0.1 F600\n"), S(b"$J=G91 Z-0.1 F600\n"), Q(sleep_s=0.5, mask="motion"),
        S(b"G4 P0\n"), *SOFT_LIMITS_ON, S(b"$J=G91 X10 F600\n"),
        S(b"$J=G53 X-201 F600\n"), Q(mask="motion"),
    ],
    "soft limits and critical alarms": [
        *FAST, *SOFT_LIMITS_ON, Q(mask="motion"), S(b"G0 X1\n", b"ALARM:2\r\n"),
        S(b"\x18", b"", quiet_s=0.0), S(b"?", b"[MSG:Reset to continue]\r\n", quiet_s=1.0),
        S(b"G0 X-1\n", b"", quiet_s=0.3), S(b"\x18", b"unlock]\r\n", quiet_s=0.3), Q(mask="motion"),
        S(b"G0 X-1\n"), S(b"$X\n"), S(b"G1 X-0.5 F60\n"), S(b"G1 X0.5\n", b"ALARM:2\r\n", mask="motion"),
        S(b"", b"[MSG:Reset to continue]\r\n", quiet_s=0.3), Q(sleep_s=0.2, until=b"", quiet_s=0.5),
        S(b"\x18", b"unlock]\r\n", quiet_s=0.3), Q(mask="motion"), S(b"$X\n"), S(b"$22=0\n"), S(b"$$\n"),
    ],
    "homing": [
        S(b"$H\n"), S(b"$22=1\n"), S(b"$H\n", b"unlock]\r\n", quiet_s=0.3, mask="motion"), Q(mask="motion"),
        S(b"G0 X-1\n"), S(b"$X\n"),
    ],
}

#: exchanges whose replies the emulator is not held to, and why (the firmware is right;
#: these are what grbl-sim cannot show of a real board)
LEFT_OUT = {
    "homing": "grbl-sim reads every limit pin active, so its homing cycle fails (ALARM:8); the "
              "emulator models a board whose switches work",
}


def _read(fd: int, until: bytes | None, quiet_s: float, timeout_s: float) -> bytes:
    data, deadline = b"", time.monotonic() + timeout_s
    done = (lambda d: True) if until == b"" else (
        (lambda d: OK_OR_ERROR.search(d) is not None) if until is None else (lambda d: d.endswith(until)))
    while not done(data):
        left = deadline - time.monotonic()
        if left <= 0:
            raise TimeoutError(f"no complete reply within {timeout_s} s; got {data!r}")
        if select.select([fd], [], [], min(left, 0.05))[0]:
            data += os.read(fd, 4096)
    last = time.monotonic()
    while time.monotonic() - last < quiet_s:
        if select.select([fd], [], [], quiet_s)[0]:
            data += os.read(fd, 4096)
            last = time.monotonic()
    return data


def record(fd: int, steps: list[dict], timeout_s: float = 120.0) -> list[bytes]:
    """Play ``steps`` on the open device ``fd``; returns each step's reply."""
    replies = []
    for step in steps:
        time.sleep(step["sleep_s"])
        if step["send"]:
            os.write(fd, step["send"])
        replies.append(_read(fd, step["until"], step["quiet_s"], timeout_s))
    return replies


def replay_on_emulator(emulator, steps: list[dict], dt_s: float = 0.001, cap_s: float = 60.0) -> list[bytes]:
    """Play ``steps`` on ``emulator`` with its clock advanced in ``dt_s`` ticks (virtual time)."""
    now, replies = 1.0, []
    emulator.pop_output(now)                                     # the power-up banner

    def run_for(seconds: float, stop=lambda d: False) -> bytes:
        nonlocal now
        out, end = b"", now + seconds
        while now < end and not stop(out):
            now += dt_s
            emulator.tick(now)
            out += emulator.pop_output(now)
        return out

    for step in steps:
        run_for(step["sleep_s"])
        if step["send"]:
            emulator.receive(step["send"], now)
            emulator.tick(now)
        until = step["until"]
        done = (lambda d: True) if until == b"" else (
            (lambda d: OK_OR_ERROR.search(d) is not None) if until is None else (lambda d: d.endswith(until)))
        out = emulator.pop_output(now)
        out += run_for(cap_s, lambda d, out=out: done(out + d)) if not done(out) else b""
        out += run_for(max(step["quiet_s"], 0.05))
        replies.append(out)
    return replies


_PINS = re.compile(rb"\|Pn:[A-Z]+")
_NUMBER = re.compile(rb"-?\d+(?:\.\d+)?")


def comparable(reply: bytes, mask: str | None) -> bytes:
    """``reply`` without the simulator's pin field, numbers of status reports masked if asked."""
    reply = _PINS.sub(b"", reply)
    if mask == "motion":
        reply = re.sub(rb"<[^>]*>", lambda m: _NUMBER.sub(b"#", m.group()), reply)
    return reply
