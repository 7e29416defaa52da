"""Robot probe: exact footprint CDFs, smoothing against an independent quadrature, the
closed-form displacement of one touch, the touch draws, and the validation branches."""
import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from feeler.errors import ArgumentError
from feeler.models.probe import (Footprint, Motion, ProbeParams, Touch, draw_touch, smoothed_height_mm,
                                 tip_displacement)
from feeler.models.surface import grating, step


def test_flat_face_is_a_uniform_footprint():
    f = Footprint(width_mm=2.0, press_mm=0.05, tilt_deg=0.0)
    np.testing.assert_allclose(f.cdf([-2.0, -1.0, -0.5, 0.0, 0.5, 1.0, 3.0]), [0, 0, 0.25, 0.5, 0.75, 1, 1])


def test_steep_tilt_gives_a_triangle_at_the_trailing_corner():
    # press 0.05 mm, tan(tilt) = 0.1 -> contact length 0.5 mm from the corner at -1 mm
    tilt = math.degrees(math.atan(0.1))
    f = Footprint(2.0, 0.05, tilt)
    s = np.array([0.0, 0.25, 0.5, 1.0])
    expected = 1 - (1 - np.minimum(s, 0.5) / 0.5) ** 2   # triangle density 2(1 - s/l)/l
    np.testing.assert_allclose(f.cdf(s - 1.0), expected, atol=1e-12)
    mirrored = Footprint(2.0, 0.05, -tilt)
    np.testing.assert_allclose(mirrored.cdf(1.0 - s), 1 - f.cdf(s - 1.0), atol=1e-12)


def test_point_contact_follows_the_profile():
    p = step(5.0, 0.1)
    x = np.array([4.0, 4.999, 5.0, 6.0])
    np.testing.assert_array_equal(smoothed_height_mm(p, x, Footprint(0.0, 0.05)), p.height_mm(x))


@settings(max_examples=25, deadline=None)
@given(width=st.floats(0.2, 3.0), press=st.floats(0.01, 0.2), tilt=st.floats(-10, 10))
def test_cdf_is_a_distribution(width, press, tilt):
    f = Footprint(width, press, tilt)
    r = np.linspace(-width, width, 201)
    c = f.cdf(r)
    assert c[0] == 0.0 and c[-1] == pytest.approx(1.0)
    assert np.all(np.diff(c) >= -1e-12)


@settings(max_examples=15, deadline=None)
@given(width=st.floats(0.3, 2.0), press=st.floats(0.02, 0.1), tilt=st.floats(-6, 6), x=st.floats(3.0, 7.0))
def test_smoothing_matches_quadrature_of_the_winkler_pressure(width, press, tilt, x):
    """Independent reference: integrate pressure x height on a fine grid (midpoint rule)."""
    profile = grating(4.0, 1.0, 0.03, 2, duty=0.4)
    r = (np.arange(100000) + 0.5) / 100000 * width - width / 2
    g = math.tan(math.radians(abs(tilt)))
    depth = press - g * ((r + width / 2) if tilt >= 0 else (width / 2 - r))
    pressure = np.clip(depth, 0, None)
    ref = np.sum(pressure * profile.height_mm(x + r)) / pressure.sum()
    got = smoothed_height_mm(profile, x, Footprint(width, press, tilt))
    assert got == pytest.approx(ref, abs=2e-6)


def test_motion_sampling():
    m = Motion(speed_mm_s=0.5, traverse_mm=10.0, dt_s=0.5)
    assert m.n_samples == 41
    np.testing.assert_allclose(m.times_s()[[0, 1, -1]], [0.0, 0.5, 20.0])
    assert Motion(0.3, 1.0, 1.0).n_samples == 4          # 0, 0.3, 0.6, 0.9 mm


def test_one_touch_in_closed_form():
    m = Motion(0.5, 10.0, 0.5)
    params = ProbeParams(pad_width_mm=1.0, shear_per_normal=0.2, breakaway_frac=0.5, breakaway_s=0.2)
    touch = Touch(uy0_mm=0.04, tilt_deg=0.0, x0_mm=0.0, drift_mm_s=0.001)
    t, x, u = tip_displacement(step(5.0, 0.1), m, params, touch)
    np.testing.assert_allclose(x, 0.5 * t)
    ramp = np.clip((x - 4.5) / 1.0, 0, 1)                 # flat 1 mm face: linear rise over 4.5..5.5 mm
    expected_uy = 0.04 + 0.1 * ramp - 0.5 * 0.04 * (1 - np.exp(-t / 0.2)) + 0.001 * t
    np.testing.assert_allclose(u[:, 1], expected_uy, atol=1e-15)
    np.testing.assert_allclose(u[:, 0], -0.2 * expected_uy, atol=1e-15)
    np.testing.assert_array_equal(u[:, 2], 0.0)
    assert u.shape == (41, 3)


def test_a_snapping_touch_takes_each_rising_edge_in_one_jump():
    m = Motion(0.5, 10.0, 0.5)
    params = ProbeParams(pad_width_mm=1.0)
    touch = Touch(uy0_mm=0.04, tilt_deg=3.0, x0_mm=0.1, drift_mm_s=0.0, snaps=True)
    t, x, u = tip_displacement(step(5.0, 0.1), m, params, touch)
    np.testing.assert_allclose(u[:, 1], 0.04 + 0.1 * (x >= 5.0), atol=1e-15)
    assert np.count_nonzero(np.diff(u[:, 1])) == 1             # the whole step within one frame
    ride = tip_displacement(step(5.0, 0.1), m, params, replace(touch, snaps=False))[2][:, 1]
    assert ride[-1] == pytest.approx(u[-1, 1]) and np.count_nonzero(np.diff(ride)) > 1
    # a falling edge is still smoothed by the face (the snap is a catch on a riser)
    grate = grating(3.0, 4.0, 0.1, 1)
    down = smoothed_height_mm(grate, x, Footprint(1.0, 0.04), snap=True)
    np.testing.assert_allclose(down, smoothed_height_mm(grate, x, Footprint(1.0, 0.04))
                               + 0.1 * ((x >= grate.edges_mm[0]) - (1 - Footprint(1.0, 0.04).cdf(grate.edges_mm[0] - x))),
                               atol=1e-15)


def test_snap_draws_follow_snap_prob_and_leave_the_other_draws_alone():
    m = Motion(0.5, 10.0, 0.5)
    base = ProbeParams(uy0_mean_mm=0.05, uy0_sd_mm=0.01, tilt_sd_deg=2.0)
    snapping = replace(base, snap_prob=0.3)
    a = [draw_touch(base, m, np.random.default_rng(k)) for k in range(2000)]
    b = [draw_touch(snapping, m, np.random.default_rng(k)) for k in range(2000)]
    assert [replace(t, snaps=False) for t in b] == a and not any(t.snaps for t in a)
    assert np.mean([t.snaps for t in b]) == pytest.approx(0.3, abs=0.03)
    assert all(draw_touch(replace(base, snap_prob=1.0), m, np.random.default_rng(k)).snaps for k in range(20))


def test_draws_are_seeded_and_have_the_stated_spread():
    params = ProbeParams(uy0_mean_mm=0.05, uy0_sd_mm=0.01, tilt_sd_deg=2.0, x0_sd_mm=0.3, drift_sd_mm_s=1e-3)
    m = Motion(0.5, 10.0, 0.5, x0_mm=1.0)
    assert draw_touch(params, m, np.random.default_rng(3)) == draw_touch(params, m, np.random.default_rng(3))
    rng = np.random.default_rng(4)
    touches = [draw_touch(params, m, rng) for _ in range(4000)]
    uy0 = np.array([t.uy0_mm for t in touches])
    x0 = np.array([t.x0_mm for t in touches])
    assert uy0.min() > 0
    assert uy0.mean() == pytest.approx(0.05, abs=0.001) and uy0.std() == pytest.approx(0.01, rel=0.05)
    assert x0.mean() == pytest.approx(1.0, abs=0.03) and x0.std() == pytest.approx(0.3, rel=0.05)
    assert np.std([t.tilt_deg for t in touches]) == pytest.approx(2.0, rel=0.05)


def test_press_draws_are_truncated_to_positive():
    params = ProbeParams(uy0_mean_mm=0.01, uy0_sd_mm=0.02)
    rng = np.random.default_rng(0)
    assert min(draw_touch(params, Motion(1, 1, 0.1), rng).uy0_mm for _ in range(300)) > 0


@pytest.mark.parametrize("make, name", [
    (lambda: Motion(0.0, 10.0, 0.5), "speed_mm_s"),
    (lambda: Motion(0.5, float("inf"), 0.5), "traverse_mm"),
    (lambda: Motion(0.5, 10.0, -0.5), "dt_s"),
    (lambda: ProbeParams(pad_width_mm=-1.0), "pad_width_mm"),
    (lambda: ProbeParams(breakaway_frac=float("nan")), "breakaway_frac"),
    (lambda: ProbeParams(uy0_mean_mm=0.0), "uy0_mean_mm"),
    (lambda: ProbeParams(breakaway_s=0.0), "breakaway_s"),
    (lambda: ProbeParams(snap_prob=1.5), "snap_prob"),
    (lambda: ProbeParams(snap_prob=float("nan")), "snap_prob"),
])
def test_invalid_motion_and_params_name_the_argument(make, name):
    with pytest.raises(ArgumentError) as info:
        make()
    assert info.value.name == name


def test_one_rule_gives_the_samples_of_a_scan():
    """The simulated probe, a robot scene's frame count and an acquisition plan take the
    samples of a scan by one rule, floor(traverse / (v·dt)) + 1 (it was written out in three
    places)."""
    from feeler.models.probe import samples_per_scan
    from feeler.scenes import scan_plan

    assert scan_plan.samples_per_scan is samples_per_scan
    for speed, traverse, dt in ((0.3, 1.0, 1.0), (1.0, 10.0, 0.1), (20.0, 40.0, 0.005), (3.0, 0.9, 0.1)):
        assert Motion(speed, traverse, dt).n_samples == samples_per_scan(speed, traverse, dt)
    assert samples_per_scan(1.0, 10.0, 0.1) == 101 and samples_per_scan(3.0, 0.9, 0.1) == 4
