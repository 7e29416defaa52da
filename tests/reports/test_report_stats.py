"""Intervals of the report's empirical 2AFC proportions."""
import numpy as np
import pytest

from feeler.calib.neuron.discriminate import separation_bound
from feeler.datasets import proportion_correct
from feeler.reports.stats import bootstrap_interval, pc_interval


def test_plates_whose_scans_never_overlap_get_a_bound_not_a_zero_width_interval():
    """24 scans a plate, every pair told apart: every resample says 1, and the report printed
    "1 [1, 1]" (an outside review); 24 disjoint pairs all correct bound P(correct) below at
    0.025^(1/24) = 0.858."""
    rng = np.random.default_rng(4)
    low, high = rng.normal(0.0, 0.1, 24), rng.normal(5.0, 0.1, 30)
    assert proportion_correct(low, high) == 1.0 and bootstrap_interval(proportion_correct, [low, high]) == (1.0, 1.0)
    lo, hi = pc_interval(low, high)
    assert lo == pytest.approx(separation_bound(24)) == pytest.approx(0.8575, abs=1e-4) and hi == 1.0
    lo, hi = pc_interval(high, low)                                   # none told apart: the mirror bound
    assert lo == 0.0 and hi == pytest.approx(1.0 - separation_bound(24))
    mixed_low, mixed_high = rng.normal(0.0, 1.0, 24), rng.normal(1.0, 1.0, 24)      # overlapping: the bootstrap's
    assert pc_interval(mixed_low, mixed_high) == bootstrap_interval(proportion_correct, [mixed_low, mixed_high])
