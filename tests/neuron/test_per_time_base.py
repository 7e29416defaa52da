"""Records with their own sample times (acquired scans): grouped calls equal per-record calls."""
import numpy as np
import pytest

from feeler.calib.neuron.fit import NeuronData, shared_times
from feeler.calib.neuron.model import peak_table
from feeler.errors import ArgumentError
from feeler.models import neuron


def _records(rng, n_rec=5, n=60):
    base = np.arange(n) * 0.05
    t = np.stack([base + rng.uniform(0, 0.02, n) for _ in range(n_rec)])
    t[2] = t[0]                                              # two records share a time base
    strain = np.cumsum(rng.normal(0, 1e-3, (n_rec, n)), axis=1)
    return strain, t


def test_grouped_calls_equal_one_call_per_record():
    strain, t = _records(np.random.default_rng(0))
    got = neuron.per_time_base(lambda s, tt: neuron.pulse_density(s, tt, a=2.0, tau=0.3, h=0.0), strain, t)
    want = np.stack([neuron.pulse_density(strain[i], t[i], a=2.0, tau=0.3, h=0.0) for i in range(len(t))])
    np.testing.assert_array_equal(got, want)
    shared = neuron.per_time_base(lambda s, tt: neuron.window_sum(s, tt, tau=0.3), strain, t[0])
    np.testing.assert_array_equal(shared, neuron.window_sum(strain, t[0], tau=0.3))


def test_peak_table_and_neuron_data_take_per_scan_times():
    strain, t = _records(np.random.default_rng(1))
    table = peak_table(strain, t, tau_lo_s=0.05, tau_hi_s=1.0, n_grid=16)
    for i in range(len(t)):
        one = peak_table(strain[i:i + 1], t[i], tau_lo_s=0.05, tau_hi_s=1.0, n_grid=16)
        np.testing.assert_array_equal(table.peak[i], one.peak[0])
    data = NeuronData(strain=strain, t_s=t, step_mm=np.zeros(len(t)), length_mm=1.0)
    grid = data.table(n_grid=8).log_tau
    assert np.isclose(np.exp(grid[-1]), np.min(t[:, -1] - t[:, 0]) / 2)
    assert shared_times(np.tile(t[0], (3, 1))).shape == t[0].shape and shared_times(t).shape == t.shape


def test_mismatched_time_rows_are_refused():
    with pytest.raises(ArgumentError, match="argument t="):
        neuron.per_time_base(lambda s, tt: s, np.zeros((3, 4)), np.zeros((2, 4)))
