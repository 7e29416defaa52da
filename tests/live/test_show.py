"""What a person watching a decode sees: a rewritten line on a terminal, a line per
decision elsewhere."""

import io
import math

import numpy as np

from feeler.calib.neuron.live import Decision, LiveState
from feeler.calib.neuron.live.show import LiveView


class _H:
    def get(self):
        return (0.1, 0.09, 0.11)


def _state(n, decision=None, new=False, flags=()):
    return LiveState(n, 0.5 * n, np.array([0.2, 0.8]), _H(), 0.07, False, decision, new, flags)


ROW = {"scan_id": 3, "p_0mm": 0.2, "p_0.1mm": 0.8, "height_mm": 0.1, "lo90_mm": 0.09, "hi90_mm": 0.11,
       "decided_mm": 0.1, "flagged": False, "flag": ""}


def test_off_a_terminal_one_line_per_decision_and_per_odd_scan():
    out = io.StringIO()
    view = LiveView([0.0, 0.1], stream=out, live=False)
    d = Decision(0.1, 0.8, 4, 2.0, math.nan)
    for n in range(6):
        view.on_state(3, _state(n, d if n >= 4 else None, new=n == 4))
    view.on_scan(ROW)                                   # decided, not flagged: nothing more
    view.on_scan({**ROW, "decided_mm": math.nan, "flagged": True, "flag": "speed 2 mm/s"})
    lines = out.getvalue().splitlines()
    assert len(lines) == 2 and "decided 0.1 mm (p 0.800) at t 2.000 s" in lines[0]
    assert "undecided" in lines[1] and "flagged: speed 2 mm/s" in lines[1]


def test_on_a_terminal_the_line_is_rewritten_at_most_every_interval():
    out, now = io.StringIO(), [0.0]
    view = LiveView([0.0, 0.1], stream=out, live=True, every_s=1.0, clock=lambda: now[0])
    for n in range(10):
        now[0] = 0.25 * n
        view.on_state(3, _state(n))
    assert out.getvalue().count("\r") == 3                 # t = 0, 1 and 2 s
    assert "z 0.07 mm" in out.getvalue() and "0.1:0.80" in out.getvalue()
    view.on_state(3, _state(10, Decision(0.1, 0.8, 10, 5.0, 1.0), new=True))      # a decision shows at once
    assert out.getvalue().count("\r") == 4 and "decided 0.1 mm" in out.getvalue()
    view.on_scan(ROW)
    assert out.getvalue().endswith("\n") and "scan 3: end" in out.getvalue().splitlines()[-1]
