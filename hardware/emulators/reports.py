"""What the emulated Grbl 1.1h prints: status reports (with Grbl's refresh counters), ``$G``
and ``$#``, in Grbl's field order and number format.

A status report is ``<State|MPos:x,y,z|Bf:b,r|FS:f,s|WCO:x,y,z|Ov:f,r,s|A:SF>``: ``WPos``
instead of ``MPos`` when ``$10`` bit 0 is clear, ``Bf`` when bit 1 is set, values in
inches with ``$13=1``. ``WCO`` comes on the first report after a reset or an offset
change, then every 10th report when idle (30th when busy); ``Ov`` (and ``A`` when the
spindle or coolant is on) on the report after a ``WCO``, then every 10th (20th busy), and
on the next report after a spindle or coolant change. A real board with its switches
released reports no ``Pn`` field.
"""
from __future__ import annotations

from feeler.hardware.emulators.settings import grbl_float

__all__ = ["Reporter", "gcode_modes", "ngc_parameters", "BUSY"]

BUSY = ("Home", "Run", "Hold", "Jog", "Door")


def _coords(values, inches: bool) -> str:
    return ",".join(grbl_float(v / 25.4 if inches else v, 4 if inches else 3) for v in values)


def _rate(mm_min: float, inches: bool) -> str:
    return grbl_float(mm_min / 25.4 if inches else mm_min, 1 if inches else 0)


class Reporter:
    """Grbl's ``report_wco_counter`` and ``report_ovr_counter`` (both 0 after a reset)."""

    def __init__(self):
        self.wco_counter = self.ovr_counter = 0

    def status(self, state: str, settings: dict, mpos, wco, feed_mm_min: float, spindle_rpm: float,
               accessory: str, buffers: tuple[int, int]) -> str:
        """One report (without its line end).

        Args:
            state (str): e.g. ``"Idle"``, ``"Hold:0"``; mpos, wco (3 floats, mm).
            accessory (str): ``"S"``/``"C"`` spindle on, ``"F"`` flood coolant, or ``""``.
            buffers (tuple[int, int]): free planner blocks, free receive-buffer bytes.
        """
        inches, mask = bool(settings[13]), int(settings[10])
        busy = state.split(":")[0] in BUSY
        pos = mpos if mask & 1 else tuple(p - w for p, w in zip(mpos, wco))
        out = [f"<{state}|{'MPos' if mask & 1 else 'WPos'}:{_coords(pos, inches)}"]
        if mask & 2:
            out.append(f"|Bf:{buffers[0]},{buffers[1]}")
        out.append(f"|FS:{_rate(feed_mm_min, inches)},{grbl_float(spindle_rpm, 0)}")
        if self.wco_counter > 0:
            self.wco_counter -= 1
        else:
            self.wco_counter = (30 if busy else 10) - 1
            self.ovr_counter = self.ovr_counter or 1
            out.append(f"|WCO:{_coords(wco, inches)}")
        if self.ovr_counter > 0:
            self.ovr_counter -= 1
        else:
            self.ovr_counter = (20 if busy else 10) - 1
            out.append("|Ov:100,100,100" + (f"|A:{accessory}" if accessory else ""))
        return "".join(out) + ">"


def gcode_modes(parser, inches_reports: bool) -> str:
    """``$G``: ``[GC:G0 G54 G17 G21 G90 G94 M5 M9 T0 F0 S0]``."""
    m = parser.modal
    words = [f"G{m.motion}", f"G{54 + m.coord_select}", f"G{17 + m.plane}", "G20" if m.inches else "G21",
             f"G{90 + m.distance}", "G94"]
    if m.program_flow:
        words.append("M0" if m.program_flow == 3 else f"M{m.program_flow}")
    words += [f"M{m.spindle}", "M8" if m.coolant else "M9", f"T{parser.tool}",
              f"F{_rate(parser.feed_mm_min, inches_reports)}", f"S{grbl_float(parser.spindle_rpm, 0)}"]
    return "[GC:" + " ".join(words) + "]"


def ngc_parameters(stored, parser, inches: bool) -> list[str]:
    """``$#``: the stored coordinates, G92, tool length offset and probe lines."""
    names = [f"G{54 + i}" for i in range(6)] + ["G28", "G30"]
    lines = [f"[{name}:{_coords(xyz, inches)}]" for name, xyz in zip(names, stored)]
    tlo = grbl_float(parser.tlo / 25.4 if inches else parser.tlo, 4 if inches else 3)
    return lines + [f"[G92:{_coords(parser.g92, inches)}]", f"[TLO:{tlo}]",
                    f"[PRB:{_coords((0.0, 0.0, 0.0), inches)}:0]"]
