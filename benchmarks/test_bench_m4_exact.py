"""M4 exact backend beside psignifit 4 on the shipped psychophysics-2afc data (synthetic).

The shipped data are 6 subjects × 2 conditions; a psignifit user fits them as 14
psychometric functions (12 subject × condition fits and 2 pooled fits, one per
condition). feeler fits the same 14 with ``backend="exact", lapse_per="condition"`` (the
model psignifit fits, with the priors matched as in ``tests/psy/psignifit_ref.py``).

Measured in the same process, rounds interleaved (feeler, psignifit default grid,
psignifit 100 × 100 × 40 grid): wall time of the 14 fits, medians and spread, and the
ratio of medians. Accuracy of each against a reference (feeler's exact grid at 3× the
nodes per axis, itself checked against a brute-force integral in tests/psy): the largest
error over the 14 rows of the PSE and DT means and 95 % bounds, in % of the interval
width. ``fit_seconds`` is FitResult.seconds (backend, summaries, checks), the wall time
also includes the posterior's summary and diagnostics (ArviZ).
"""
import os
import statistics
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

from _ratios import record_ratio
from feeler.calib.psychometric.model.cells import make_cells
from feeler.calib.psychometric.exact.grid import GridSpec
from feeler.calib.psychometric.fit import fit_psychometric, threshold_table
from feeler.calib.psychometric.model.priors import Priors
from feeler.psydata import read_trials
from feeler.scene import load_scene
from feeler.simulate.psychophysics import simulate_psychophysics

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "psy"))
pytest.importorskip("psignifit")
from psignifit_ref import grid_summary, psignifit_fit  # noqa: E402

ROUNDS = int(os.environ.get("FEELER_BENCH_ROUNDS", "3"))
FINE = {"threshold": 100, "width": 100, "lambda": 40}


@pytest.fixture(scope="module")
def trials():
    with tempfile.TemporaryDirectory() as tmp:
        scene = load_scene("datasets-synthetic/psychophysics-2afc.toml")
        return read_trials(simulate_psychophysics(scene, tmp)["trials"])


def _feeler(trials, grid=GridSpec()):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fit_psychometric(trials, rng=np.random.default_rng(0), lapse_per="condition", grid=grid)


def _psignifit_all(trials, steps):
    """The 14 fits: every subject × condition, then every condition pooled."""
    cells = make_cells(trials).canonical()
    resolved = Priors().resolve(cells)
    out = {}
    for c in range(len(cells.conditions)):
        for o, label in list(enumerate(cells.subjects)) + [(-1, "all")]:
            src = cells.pooled() if o < 0 else cells
            sel = (src.condition == c) & ((src.subject == o) if o >= 0 else True)
            res = psignifit_fit(src.x_um[sel], src.n[sel], src.k[sel], resolved, c, steps=steps,
                                max_bound_value=1e-5)
            out[(label, cells.conditions[c][1])] = grid_summary(res)
    return out


def _errors(table, ref) -> float:
    """Largest |difference| of PSE/DT mean and bounds over the rows, % of the width."""
    worst = 0.0
    for row in table.itertuples(index=False):
        r = ref[(ref.subject == row.subject) & (ref.standard_speed_mm_s == row.standard_speed_mm_s)].iloc[0]
        for q in ("pse", "dt"):
            got = np.array([getattr(row, f"{q}_um"), getattr(row, f"{q}_lb_um"), getattr(row, f"{q}_ub_um")])
            want = np.array([r[f"{q}_um"], r[f"{q}_lb_um"], r[f"{q}_ub_um"]])
            worst = max(worst, float(np.max(np.abs(got - want)) / (want[2] - want[1])))
    return 100 * worst


def test_exact_beside_psignifit(benchmark, trials):
    _feeler(trials)                                     # imports and caches warmed
    feeler_s, fit_s, default_s, fine_s = [], [], [], []
    state = {}

    def psignifit_round():
        t0 = time.perf_counter()
        state["default"] = _psignifit_all(trials, None)
        default_s.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        state["fine"] = _psignifit_all(trials, FINE)
        fine_s.append(time.perf_counter() - t0)

    def feeler_round():
        t0 = time.perf_counter()
        state["result"] = _feeler(trials)
        feeler_s.append(time.perf_counter() - t0)
        fit_s.append(state["result"].seconds)

    benchmark.pedantic(feeler_round, setup=psignifit_round, rounds=ROUNDS, iterations=1)
    table = threshold_table(state["result"])
    ref = threshold_table(_feeler(trials, GridSpec(n_pse=96, n_s=96, n_l=72)))
    err = {"feeler_exact": _errors(table, ref),
           "psignifit_default": _errors_vs(state["default"], ref),
           "psignifit_100x100x40": _errors_vs(state["fine"], ref)}
    med = {k: statistics.median(v) for k, v in (("feeler", feeler_s), ("fit", fit_s),
                                                 ("default", default_s), ("fine", fine_s))}
    spread = {k: (min(v), max(v)) for k, v in (("feeler", feeler_s), ("fit", fit_s),
                                               ("default", default_s), ("fine", fine_s))}
    benchmark.extra_info.update({"rows": len(table), "verdict_ok": state["result"].verdict.ok,
                                 **{f"median_{k}_s": v for k, v in med.items()},
                                 **{f"spread_{k}_s": f"{a:.3f}-{b:.3f}" for k, (a, b) in spread.items()},
                                 **{f"max_error_pct_width_{k}": v for k, v in err.items()}})
    print(f"\n14 fits, {ROUNDS} interleaved rounds (medians, [min, max]):")
    for k in med:
        print(f"  {k:8s} {med[k]:7.3f} s  [{spread[k][0]:.3f}, {spread[k][1]:.3f}]")
    print("  largest PSE/DT error vs the fine exact grid (% of the 95 % width): "
          + ", ".join(f"{k} {v:.2f}" for k, v in err.items()))
    record_ratio(benchmark, "psignifit_default_over_feeler_exact_wall", med["default"] / med["feeler"], "> 1")
    record_ratio(benchmark, "psignifit_100x100x40_over_feeler_exact_wall", med["fine"] / med["feeler"], "> 1")
    record_ratio(benchmark, "feeler_exact_fit_seconds_14_fits", med["fit"], "<= 2 (quiet machine)")


def _errors_vs(psig: dict, ref) -> float:
    worst = 0.0
    for (subject, speed), summary in psig.items():
        r = ref[(ref.subject == subject) & (ref.standard_speed_mm_s == speed)].iloc[0]
        for q in ("pse", "dt"):
            want = np.array([r[f"{q}_um"], r[f"{q}_lb_um"], r[f"{q}_ub_um"]])
            worst = max(worst, float(np.max(np.abs(np.array(summary[q]) - want)) / (want[2] - want[1])))
    return 100 * worst
