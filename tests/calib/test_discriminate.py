"""M3: 2AFC probabilities from the forward model and an M2 posterior."""
import warnings

import numpy as np
import pytest

from feeler.calib.neuron.discriminate import Discriminator, _crossing
from feeler.calib.neuron import fit_neuron
from feeler.calib.neuron.synth import scene_scans
from feeler.errors import ArgumentError


@pytest.fixture(scope="module")
def disc():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")            # the PPC's per-plate bias note
        res = fit_neuron(scene_scans()[2], seed=4, draws=500)
    return Discriminator(res, n_scans=300, n_draws=100, seed=9)


def test_equal_heights_give_one_half(disc):
    for height in (0.0, 0.1):
        p = disc.pc(height, height)
        print(f"\nP(correct) at {height} vs {height} mm: {p.mean:.3f} [{p.lo95:.3f}, {p.hi95:.3f}]")
        assert abs(p.mean - 0.5) < 0.05 and p.lo95 <= 0.5 + 0.02 and p.hi95 >= 0.5 - 0.02


def test_proportion_correct_grows_with_the_increment(disc):
    means = [disc.pc(0.1, 0.1 + d).mean for d in (0.0, 0.004, 0.008, 0.016, 0.05)]
    print("\nP(correct) vs increment:", np.round(means, 3))
    assert np.all(np.diff(means) > 0) and means[-1] > 0.99


def test_threshold_and_weber(disc):
    th = disc.threshold(0.1)
    d = th.delta75_mm
    print(f"\ndelta75 {d.mean * 1e3:.2f} um [{d.lo95 * 1e3:.2f}, {d.hi95 * 1e3:.2f}], Weber {th.weber.mean:.3f}")
    assert th.found == 1.0 and 0 < d.lo95 <= d.mean <= d.hi95 < 0.025
    np.testing.assert_allclose(th.weber.draws, d.draws / 0.1)
    assert disc.pc(0.1, 0.1 + d.mean).mean == pytest.approx(0.75, abs=0.06)


def test_pse_at_equal_speeds_is_the_reference(disc):
    p = disc.pse(0.1, 0.5, 0.5, span_mm=0.03, n_steps=12)
    print(f"\nPSE at equal speeds: {p.mean:.4f} [{p.lo95:.4f}, {p.hi95:.4f}] mm")
    assert abs(p.mean - 0.1) < 0.005


def test_proportion_correct_exact_counts():
    lo = np.array([[1.0, 2.0, 3.0]])
    hi = np.array([[2.0, 4.0]])
    # pairs (hi > lo): 2>1, 4>1,2,3 = 4 wins, one tie (2 = 2): (4 + 0.5) / 6
    assert Discriminator.proportion_correct(lo, hi)[0] == pytest.approx(4.5 / 6)


def test_crossing_exact():
    x = np.array([0.0, 1.0, 2.0, 3.0])
    curve = np.array([[0.5, 0.6, 0.8, 0.9], [0.8, 0.9, 0.9, 0.9], [0.5, 0.6, 0.7, 0.7]])
    out = _crossing(x, curve, 0.75)
    assert out[0] == pytest.approx(1.75) and np.isnan(out[1]) and np.isnan(out[2])


def test_bad_arguments(disc):
    with pytest.raises(ArgumentError, match="reference_mm"):
        disc.threshold(0.0)
    with pytest.raises(ArgumentError, match="n_scans"):
        Discriminator(None, n_scans=1)
