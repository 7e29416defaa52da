"""Sensor interface: the displacement fidelity, the dispatch and its refusals."""
import numpy as np
import pytest

from feeler.errors import ArgumentError
from feeler.models import sensor
from feeler.models.sensor import DisplacementNoise, observe


def test_displacement_noise_has_the_stated_sd_per_axis_and_zero_mean():
    u = np.zeros((200, 500, 3))
    meas = observe(u, fidelity="displacement", params=DisplacementNoise(0.001, 0.002, 0.004),
                   rng=np.random.default_rng(1))
    assert meas.shape == u.shape
    sd = meas.reshape(-1, 3).std(axis=0)
    np.testing.assert_allclose(sd, [0.001, 0.002, 0.004], rtol=0.01)   # 1e5 samples: sd error ~0.2 %
    np.testing.assert_allclose(meas.reshape(-1, 3).mean(axis=0), 0.0, atol=3e-5)


def test_zero_noise_returns_the_truth_and_same_seed_same_draws():
    u = np.random.default_rng(0).normal(size=(4, 3))
    out = observe(u, fidelity="displacement", params=DisplacementNoise(0, 0, 0), rng=np.random.default_rng(5))
    np.testing.assert_array_equal(out, u)
    p = DisplacementNoise()
    a = observe(u, fidelity="displacement", params=p, rng=np.random.default_rng(7))
    b = observe(u, fidelity="displacement", params=p, rng=np.random.default_rng(7))
    np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("fidelity", ["areas", "images"])
def test_levels_not_plugged_in_yet_are_refused(monkeypatch, fidelity):
    monkeypatch.setitem(sensor.FIDELITIES, fidelity, None)
    with pytest.raises(ArgumentError, match="not available"):
        observe(np.zeros((3, 3)), fidelity=fidelity, params=None, rng=np.random.default_rng(0))


def test_unknown_fidelity_and_bad_shape_are_refused():
    with pytest.raises(ArgumentError, match="fidelity"):
        observe(np.zeros((3, 3)), fidelity="x-ray", params=None, rng=np.random.default_rng(0))
    with pytest.raises(ArgumentError, match="u_true_mm"):
        observe(np.zeros((3, 2)), fidelity="displacement", params=DisplacementNoise(), rng=np.random.default_rng(0))
    with pytest.raises(ArgumentError, match="u_true_mm"):
        observe(np.zeros(3), fidelity="displacement", params=DisplacementNoise(), rng=np.random.default_rng(0))


def test_negative_or_nan_noise_is_refused():
    with pytest.raises(ArgumentError, match="uy_sd_mm"):
        DisplacementNoise(uy_sd_mm=-1e-3)
    with pytest.raises(ArgumentError, match="uz_sd_mm"):
        DisplacementNoise(uz_sd_mm=float("nan"))


def test_a_registered_level_is_dispatched(monkeypatch):
    monkeypatch.setattr(sensor, "FIDELITIES", dict(sensor.FIDELITIES))
    sensor.register_fidelity("areas", lambda u, params, rng: u + params)
    out = observe(np.zeros((2, 3)), fidelity="areas", params=1.5, rng=np.random.default_rng(0))
    np.testing.assert_array_equal(out, 1.5)
