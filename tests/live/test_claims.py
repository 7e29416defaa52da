"""classify's check of a labelled batch against what the fit claims: 90 % of labels
inside their intervals, as many classified right as the probabilities promise."""
from fractions import Fraction
from math import comb

import numpy as np
import pandas as pd
import pytest

from feeler.calib.neuron.live.table import CLAIM_P, claims_check, plate_column

PLATES = (0.0, 0.05, 0.1)


def _table(n, inside, hits, p_max=0.9, flagged=0):
    """n scans labelled 0.05 mm: the first ``inside`` with the label inside their interval,
    the first ``hits`` classified as it, each with top probability ``p_max``; the last
    ``flagged`` flagged."""
    k = np.arange(n)
    rest = (1 - p_max) / 2
    return pd.DataFrame({"step_mm": 0.05, "plate_mm": np.where(k < hits, 0.05, 0.1),
                         plate_column(0.0): rest, plate_column(0.05): np.where(k < hits, p_max, rest),
                         plate_column(0.1): np.where(k < hits, rest, p_max),
                         "lo90_mm": np.where(k < inside, 0.04, 0.07), "hi90_mm": np.where(k < inside, 0.06, 0.09),
                         "flagged": k >= n - flagged})


def _binom_cdf(k, n):
    """Lower tail of Binomial(n, 0.9) at k, summed exactly in integers (reference for scipy's)."""
    return float(Fraction(sum(comb(n, j) * 9 ** j for j in range(k + 1)), 10 ** n))


def test_coverage_fires_exactly_where_the_binomial_tail_and_the_floor_say():
    n = 200
    edge = max(k for k in range(n) if _binom_cdf(k, n) < CLAIM_P)    # 165: 82.5 % < 85 %
    assert edge / n < 0.85
    fired = claims_check(_table(n, edge, n), PLATES)
    assert len(fired) == 1 and f"{edge} of {n} labels inside their 90 % interval" in fired[0]
    assert "wrong" in fired[0] and "calibrate with scans like them" in fired[0]
    assert claims_check(_table(n, edge + 1, n), PLATES) == []


def test_a_significant_but_small_shortfall_over_many_scans_is_not_a_warning():
    """86 % of 5000 is far beyond chance for a 90 % interval but within what the issue's
    band allows (0.85): the summary states it; no warning."""
    assert _binom_cdf(4300, 5000) < 1e-12
    assert claims_check(_table(5000, 4300, 5000), PLATES) == []


def test_accuracy_below_what_the_probabilities_promised():
    # 100 scans at 0.99: about 1 miss expected; 10 misses is p ~ 1e-7 and 9 points short
    fired = claims_check(_table(100, 100, 90, p_max=0.99), PLATES)
    assert len(fired) == 1 and "90 of 100 classified as their labelled plate where they promised 99" in fired[0]
    assert claims_check(_table(100, 100, 97, p_max=0.99), PLATES) == []       # 3 misses: p 0.08
    # at 0.7 promised, 60 % right of 100 is within chance
    assert claims_check(_table(100, 100, 60, p_max=0.7), PLATES) == []
    both = claims_check(_table(100, 50, 50, p_max=0.99), PLATES)
    assert len(both) == 2 and "intervals" in both[0] and "over-confident" in both[1]


@pytest.mark.parametrize("case", ["unlabelled", "few", "flagged", "unknown plate"])
def test_nothing_to_judge(case):
    t = _table(100, 10, 10)
    if case == "unlabelled":
        t = t.drop(columns="step_mm")
    elif case == "few":
        t = t.iloc[:19]
    elif case == "flagged":                              # flagged scans are not the fit's to answer for
        t = _table(100, 10, 10, flagged=81)
    else:
        t = t.assign(step_mm=50.0)                       # labels in um: no trained plate
    assert claims_check(t, PLATES) == []


def _binom_sf(k, n):
    """Upper tail P(X >= k) of Binomial(n, 0.9), exactly in integers."""
    return float(Fraction(sum(comb(n, j) * 9 ** j for j in range(k, n + 1)), 10 ** n))


def test_coverage_far_above_the_claim_is_a_note_where_the_tail_and_the_band_say():
    """100 % of 96 held-out labels inside their 90 % intervals (a hard scene's plates, whose
    touches are flatter than Gaussian) was reported as a plain figure; beyond chance and
    above 95 % it is now a note that the intervals are conservative — not a warning."""
    from feeler.calib.neuron.live.table import coverage_note

    n = 200
    edge = min(k for k in range(n + 1) if _binom_sf(k, n) < CLAIM_P and k / n > 0.95)
    note = coverage_note(_table(n, edge, n), PLATES)
    assert note.startswith(f"the fit's 90 % intervals are wider than they claim for these scans: {edge} of {n} ")
    assert coverage_note(_table(n, edge - 1, n), PLATES) is None
    assert coverage_note(_table(45, 45, 45), PLATES) is None             # 0.9^45 = 0.009: chance
    assert coverage_note(_table(100, 100, 100, flagged=90), PLATES) is None      # 10 usable scans: no judgement
    assert claims_check(_table(n, n, n), PLATES) == []                    # not a warning
