"""Plate profiles: exact heights, edges, and one negative test per validation branch."""
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from feeler.errors import ArgumentError
from feeler.models.surface import Profile, grating, staircase, step


def test_step_up_and_down_heights_exact():
    up = step(5.0, 0.1)
    np.testing.assert_array_equal(up.height_mm([0.0, 4.999, 5.0, 9.0]), [0.0, 0.0, 0.1, 0.1])
    down = step(2.0, -0.05)
    np.testing.assert_array_equal(down.height_mm([1.0, 2.0]), [0.0, -0.05])
    assert up.total_rise_mm == 0.1


def test_staircase_rises_by_each_step():
    s = staircase(1.0, 2.0, 0.05, 3)
    assert s.edges_mm == (1.0, 3.0, 5.0)
    np.testing.assert_allclose(s.height_mm([0.5, 1.5, 3.5, 5.5]), [0.0, 0.05, 0.10, 0.15])


def test_grating_ridges_and_duty():
    g = grating(0.0, 1.0, 0.02, 2, duty=0.25)
    assert g.edges_mm == (0.0, 0.25, 1.0, 1.25)
    np.testing.assert_allclose(g.height_mm([0.1, 0.5, 1.1, 1.5, 3.0]), [0.02, 0.0, 0.02, 0.0, 0.0])
    assert g.total_rise_mm == 0.0


def test_base_height_offsets_everything():
    p = Profile((1.0,), (0.2,), base_mm=0.5)
    np.testing.assert_allclose(p.height_mm([0.0, 2.0]), [0.5, 0.7])


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-10, 10), min_size=1, max_size=6, unique=True),
       st.floats(-20, 20))
def test_height_is_base_plus_jumps_left_of_x(edges, x):
    edges = sorted(edges)
    jumps = [0.01 * (i + 1) for i in range(len(edges))]
    p = Profile(tuple(edges), tuple(jumps))
    expected = sum(j for e, j in zip(edges, jumps) if x >= e)
    assert p.height_mm(x) == pytest.approx(expected)


@pytest.mark.parametrize("make, name", [
    (lambda: Profile((1.0, 2.0), (0.1,)), "jumps_mm"),
    (lambda: Profile((2.0, 1.0), (0.1, 0.1)), "edges_mm"),
    (lambda: Profile((1.0, 1.0), (0.1, 0.1)), "edges_mm"),
    (lambda: Profile((float("nan"),), (0.1,)), "edges_mm"),
    (lambda: Profile((1.0,), (float("inf"),)), "edges_mm"),
    (lambda: staircase(0.0, 1.0, 0.1, 0), "n_steps"),
    (lambda: staircase(0.0, 0.0, 0.1, 2), "spacing_mm"),
    (lambda: grating(0.0, 1.0, 0.1, 0), "n_periods"),
    (lambda: grating(0.0, -1.0, 0.1, 1), "period_mm"),
    (lambda: grating(0.0, 1.0, 0.1, 1, duty=1.0), "duty"),
])
def test_invalid_profiles_name_the_argument(make, name):
    with pytest.raises(ArgumentError) as info:
        make()
    assert info.value.name == name
    assert "\n" not in str(info.value)
