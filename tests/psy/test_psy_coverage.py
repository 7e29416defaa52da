"""Coverage of the 95 % intervals over many synthetic datasets (slow validation).

``make test`` runs a few seeds; ``FEELER_FULL=1`` runs 40 (exact M4) and 20 (finger
route) and demands the rate expected of calibrated 95 % intervals.
"""
import os

import numpy as np
import pytest

from feeler.calib.psychometric.finger_route import RouteGrid, fit_finger_route, predict_p_higher
from feeler.calib.psychometric.fit import fit_psychometric, threshold_table

FULL = os.environ.get("FEELER_FULL") == "1"


@pytest.mark.slow
def test_exact_interval_coverage(simulate):
    n_sets = 40 if FULL else 3
    hits = total = 0
    for seed in range(n_sets):
        trials, truth = simulate(1000 + seed, n_subjects=6, n_trials=30)
        table = threshold_table(fit_psychometric(trials, rng=np.random.default_rng(seed), draws=200))
        table = table.set_index(["subject", "standard_speed_mm_s"])
        for t in truth:
            row = table.loc[(t.subject, t.standard_speed_mm_s)]
            hits += int(row.pse_lb_um <= t.pse_um <= row.pse_ub_um)
            hits += int(row.dt_lb_um <= t.dt_um <= row.dt_ub_um)
            total += 2
    rate = hits / total
    print(f"\nexact M4: {hits}/{total} true PSE/DT inside their 95 % intervals ({rate:.3f})")
    assert rate >= (0.92 if FULL else 0.85), f"coverage {rate:.3f} over {total} intervals"


@pytest.mark.slow
def test_finger_route_interval_coverage(simulate):
    n_sets = 20 if FULL else 2
    design, _ = simulate(0, n_subjects=6, n_trials=20)
    grid = RouteGrid(n_tau=121 if FULL else 61, n_sigma=60, n_lapse=5)
    rng = np.random.default_rng(77)
    hits = 0
    for _ in range(n_sets):
        tau = float(np.exp(rng.uniform(np.log(0.05), np.log(0.25))))
        p = predict_p_higher(design, tau_s=tau, sigma_d_um=1.2, lapse=0.02)
        data = design.assign(n_comparison_higher=rng.binomial(design.n_trials, p))
        s = fit_finger_route(data, rng=rng, grid=grid, draws=400).summary.set_index("name")
        hits += int(s.loc["tau_s", "eti95_lb"] <= tau <= s.loc["tau_s", "eti95_ub"])
    print(f"\nfinger route: true τ inside the 95 % interval in {hits}/{n_sets} datasets")
    assert hits / n_sets >= (0.85 if FULL else 0.5), f"τ covered {hits}/{n_sets}"
