"""Typed errors of the Grbl stage driver, with the Grbl 1.1 error and alarm code tables.

Device trouble is a :class:`StageError` (a :class:`feeler.errors.FeelerError`); a port the
user named that cannot be opened is a :class:`PortError` (an ``InputError``, so the CLI
prints one line and exits 2). Every error carries its data as attributes.
"""
from __future__ import annotations

from feeler.errors import FeelerError, InputError

__all__ = [
    "GRBL_ERRORS",
    "GRBL_ALARMS",
    "StageError",
    "StageTimeout",
    "StageAlarm",
    "ProtocolError",
    "StageDisconnected",
    "StageLocked",
    "PortError",
    "CRITICAL_ALARMS",
]

#: Grbl 1.1 ``error:N`` codes (from Grbl's ``error_codes_en_US.csv``).
GRBL_ERRORS: dict[int, str] = {
    1: "expected command letter (G-code words are a letter and a value)",
    2: "bad number format (missing or malformed value)",
    3: "invalid statement ('$' system command not recognised)",
    4: "value < 0 (negative value for an expected positive value)",
    5: "setting disabled (homing is not enabled)",
    6: "value < 3 us (step pulse time too short)",
    7: "EEPROM read fail, using defaults",
    8: "not idle ('$' command only valid when idle)",
    9: "G-code lock (G-code locked out during alarm or jog state)",
    10: "homing not enabled (soft limits need homing)",
    11: "line overflow (too many characters per line; line not executed)",
    12: "step rate > 30 kHz",
    13: "check door (safety door opened)",
    14: "line length exceeded (build info or startup line not stored)",
    15: "travel exceeded (jog target beyond machine travel; jog ignored)",
    16: "invalid jog command",
    17: "setting disabled (laser mode requires PWM output)",
    20: "unsupported or invalid G-code command in block",
    21: "modal group violation (two commands of one modal group in a block)",
    22: "undefined feed rate",
    23: "G-code command requires an integer value",
    24: "more than one G-code command requiring axis words in block",
    25: "repeated G-code word in block",
    26: "no axis words in block for a command that requires them",
    27: "line number value is invalid",
    28: "G-code command is missing a required value word",
    29: "G59.x work coordinate systems are not supported",
    30: "G53 only allowed with G0 and G1 motion modes",
    31: "axis words in block when no command or modal state uses them",
    32: "G2/G3 arcs require at least one in-plane axis word",
    33: "motion command target is invalid",
    34: "arc radius value is invalid",
    35: "G2/G3 arcs require at least one in-plane offset word",
    36: "unused value words in block",
    37: "G43.1 offset not assigned to the tool length axis",
    38: "tool number greater than max supported value",
}

#: Grbl 1.1 ``ALARM:N`` codes (from Grbl's ``alarm_codes_en_US.csv``).
GRBL_ALARMS: dict[int, str] = {
    1: "hard limit triggered; position likely lost, re-home",
    2: "soft limit: motion target exceeds machine travel; position retained",
    3: "reset while in motion; position likely lost, re-home",
    4: "probe fail: probe not in the expected initial state",
    5: "probe fail: probe did not contact the workpiece",
    6: "homing fail: reset during the homing cycle",
    7: "homing fail: safety door opened during homing",
    8: "homing fail: pull-off failed to clear the limit switch",
    9: "homing fail: could not find the limit switch",
    10: "homing fail: could not find the second limit switch (dual axis)",
}


#: alarms after which Grbl ignores everything but a reset (hard and soft limits)
CRITICAL_ALARMS = (1, 2)


class StageError(FeelerError):
    """Base of every error raised by the stage driver."""


class StageTimeout(StageError):
    """No complete reply before the deadline.

    Attributes:
        what (str): what was awaited, e.g. ``"reply to 'G1 X1 F600'"``.
        timeout_s (float): the deadline that passed, seconds.
        partial (bytes): bytes of an incomplete line received before the deadline; a
            non-empty ``partial`` is a short (truncated) read, never a success.
    """

    def __init__(self, what: str, timeout_s: float, partial: bytes = b""):
        self.what, self.timeout_s, self.partial = what, float(timeout_s), bytes(partial)
        tail = f"; short read {shown_bytes(self.partial)} (no line end)" if self.partial else ""
        super().__init__(f"no {what} within {self.timeout_s:.3g} s{tail}")


def shown_bytes(data: bytes, most: int = 40) -> str:
    """``data`` as Python writes bytes, its first ``most`` only (with the count beyond)."""
    data = bytes(data)
    return repr(data) if len(data) <= most else f"{data[:most]!r}... ({len(data)} bytes)"


class StageAlarm(StageError):
    """The controller reported ``ALARM:code`` (motion stopped; reset and ``$X`` to unlock).

    Attributes:
        code (int): the Grbl alarm code; ``meaning`` (str) its description.
    """

    def __init__(self, code: int):
        self.code = int(code)
        self.meaning = GRBL_ALARMS.get(self.code, "unknown alarm code")
        super().__init__(f"ALARM:{self.code} ({self.meaning})")


class ProtocolError(StageError):
    """An ``error:code`` reply, or a line that is not valid Grbl (``code`` is ``None``).

    Attributes:
        code (int | None): the Grbl error code, ``None`` for a malformed reply.
        line (bytes): the offending reply line as received.
        sent (str): the command it answered, when known (``""`` otherwise).
    """

    def __init__(self, code: int | None, line: bytes, sent: str = ""):
        self.code, self.line, self.sent = code, bytes(line), sent
        about = f" to {sent!r}" if sent else ""
        if code is None:
            text = f"malformed reply{about}: {self.line!r}"
        else:
            text = f"error:{code}{about} ({GRBL_ERRORS.get(code, 'unknown error code')})"
        super().__init__(text)


class StageDisconnected(StageError):
    """The serial port vanished (device unplugged, emulator gone).

    Attributes:
        port (str): the port path or URL; ``detail`` (str) the operating system's words.
    """

    def __init__(self, port: str, detail: str):
        self.port, self.detail = str(port), detail
        super().__init__(f"port {self.port} disconnected: {detail}")


class StageLocked(StageError, InputError):
    """The controller is in its alarm lock (``$22=1`` boots locked; or an earlier alarm) and
    the caller did not ask to home (``$H``) or unlock (``$X``) it.

    Attributes:
        port (str): the port path or URL; ``alarm`` (int | None) the alarm seen, if any.
    """

    def __init__(self, port: str, alarm: int | None = None, hint: str = "home it ($H) or unlock it ($X)"):
        self.port, self.alarm = str(port), alarm
        why = f"ALARM:{alarm}, {GRBL_ALARMS.get(alarm, 'unknown alarm')}" if alarm else \
            "Alarm state: homing is enabled ($22=1) and the board has not been homed since power-up"
        super().__init__(f"stage {self.port} is locked ({why}): {hint}")


class PortError(InputError):
    """A serial port named by the user that cannot be opened.

    Attributes:
        port (str): the port path or URL; ``problem`` (str) what is wrong and what to do.
    """

    def __init__(self, port: str, problem: str):
        self.port, self.problem = str(port), problem
        super().__init__(f"port {self.port}: {problem}")
