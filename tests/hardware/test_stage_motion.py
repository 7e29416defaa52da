"""Trapezoidal motion blocks of the emulator: closed-form cases and invariants."""
import math

import pytest
from hypothesis import given, settings, strategies as st

from feeler.hardware.emulators.motion import Block, axis_limited

coord = st.floats(-100, 100, allow_nan=False)
vec = st.tuples(coord, coord, coord)


def test_triangle_and_trapezoid_closed_form():
    tri = Block((0, 0, 0), (1, 0, 0), 100.0, 1000.0)  # never reaches 100 mm/s
    assert tri.peak_mm_s == pytest.approx(math.sqrt(1000.0))
    assert tri.duration_s == pytest.approx(2 * math.sqrt(1000.0) / 1000.0)
    trap = Block((0, 0, 0), (0, 3, 4), 10.0, 100.0)  # 5 mm: 0.1 s ramps, 0.4 s cruise
    assert trap.phases_s == pytest.approx((0.1, 0.4, 0.1))
    assert trap.at(0.3) == (pytest.approx((0, 1.5, 2.0)), 10.0)
    assert Block((1, 1, 1), (1, 1, 1), 10.0, 100.0).duration_s == 0.0


def test_axis_limits():
    assert axis_limited((0, 0, 0), (3, 4, 0), (100.0, 100.0, 1.0)) == pytest.approx(125.0)
    assert axis_limited((0, 0, 0), (0, 0, 0), (1.0, 1.0, 1.0)) == math.inf


@settings(max_examples=200, deadline=None)
@given(vec, vec, st.floats(0.1, 1000), st.floats(1, 1e5), st.floats(0, 1))
def test_profile_invariants(start, end, feed, accel, frac):
    block = Block(start, end, feed, accel)
    times = [block.duration_s * k / 50 for k in range(51)]
    dist = [block.travelled(t)[0] for t in times]
    speeds = [block.travelled(t)[1] for t in times]
    assert all(b >= a - 1e-9 for a, b in zip(dist, dist[1:]))
    assert dist[-1] == pytest.approx(block.length_mm)
    assert block.travelled(block.duration_s) == (block.length_mm, 0.0)
    assert max(speeds) <= feed * (1 + 1e-9)
    assert block.at(block.duration_s + 1.0)[0] == end
    decel, rest = block.stopping(frac * block.duration_s)
    assert decel.end_mm == rest.start_mm and rest.end_mm == end
    assert decel.length_mm + rest.length_mm == pytest.approx(
        block.length_mm - block.travelled(frac * block.duration_s)[0], abs=1e-9)
    assert decel.at(decel.duration_s)[1] == 0.0
