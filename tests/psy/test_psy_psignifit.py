"""Cross-check of the exact backend against psignifit 4 itself on matched models.

For the comparison design and for 4AFC, with psignifit configured as feeler's model (see
``psignifit_ref``), the posterior means, 95 % bounds and MAPs of the PSE (location), the
DT and the threshold at pc agree within 1 % of feeler's 95 % interval width. psignifit's
own grid (100 × 100 × 40 nodes) limits the agreement of its bounds to a few tenths of a
percent; its MAP comes from a Nelder–Mead search.
"""
import numpy as np
import pandas as pd
import pytest

from feeler.calib.psychometric.model.cells import make_cells
from feeler.calib.psychometric.fit import fit_psychometric, threshold_table
from feeler.calib.psychometric.model.priors import Priors
from feeler.calib.psychometric.model.task import Task
from feeler.psydata import KEY_COLUMNS

pytest.importorskip("psignifit")
from psignifit_ref import grid_summary, psignifit_fit  # noqa: E402

TOL = 0.01          # fraction of feeler's 95 % interval width
LEVELS = np.array([7.6, 8.4, 9.2, 10.0, 10.8, 11.6, 12.4])


def _data(seed: int, n: int, task: Task, standard: float = 10.0) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    p = task.p(LEVELS, 10.0 + rng.normal(0.0, 0.4), 1.3, 0.03)
    k = rng.binomial(n, p)
    count = "n_correct" if task.is_nafc else "n_comparison_higher"
    return pd.DataFrame([("A", standard, 20.0, x, 20.0, n, int(kk)) for x, kk in zip(LEVELS, k)],
                        columns=list(KEY_COLUMNS) + ["n_trials", count])


def _compare(row, ref: dict, names) -> dict:
    errors = {}
    for q in names:
        width = row[f"{q}_ub_um"] - row[f"{q}_lb_um"]
        mean, lb, ub = ref[q]
        errors |= {f"{q} mean": (row[f"{q}_um"] - mean) / width, f"{q} lb": (row[f"{q}_lb_um"] - lb) / width,
                   f"{q} ub": (row[f"{q}_ub_um"] - ub) / width, f"{q} map": (row[f"{q}_map_um"] - ref[f"{q}_map"]) / width}
    return errors


@pytest.mark.parametrize("seed, n", [(1, 40), (3, 20)])
def test_comparison_design_agrees_with_psignifit(seed, n):
    trials = _data(seed, n, Task())
    row = threshold_table(fit_psychometric(trials, rng=np.random.default_rng(0), lapse_per="condition")).iloc[0]
    cells = make_cells(trials).canonical()
    res = psignifit_fit(cells.x_um, cells.n, cells.k, Priors().resolve(cells))
    errors = _compare(row, grid_summary(res, pc=0.75), ("pse", "dt", "threshold"))
    bad = {k: f"{100 * v:.2f} %" for k, v in errors.items() if abs(v) > TOL}
    assert not bad, f"differences beyond {100 * TOL:g} % of the interval width: {bad}"


def test_nafc_agrees_with_psignifit():
    task = Task(4)
    trials = _data(5, 40, task, standard=0.0)
    row = threshold_table(fit_psychometric(trials, rng=np.random.default_rng(0), nafc=4,
                                           lapse_per="condition", pc=0.8)).iloc[0]
    cells = make_cells(trials, task).canonical()
    res = psignifit_fit(cells.x_um, cells.n, cells.k, Priors().resolve(cells), nafc=4)
    errors = _compare(row, grid_summary(res, nafc=4, pc=0.8), ("pse", "threshold"))
    bad = {k: f"{100 * v:.2f} %" for k, v in errors.items() if abs(v) > TOL}
    assert not bad, f"differences beyond {100 * TOL:g} % of the interval width: {bad}"
    assert row.design == "4AFC" and np.isnan(row.dt_um)


def test_a_psignifit_model_with_another_prior_disagrees():
    """The check has teeth: psignifit with the σ prior's median doubled moves the DT."""
    trials = _data(1, 40, Task())
    row = threshold_table(fit_psychometric(trials, rng=np.random.default_rng(0), lapse_per="condition")).iloc[0]
    cells = make_cells(trials).canonical()
    res = psignifit_fit(cells.x_um, cells.n, cells.k, Priors(sigma_range=0.5).resolve(cells))
    errors = _compare(row, grid_summary(res), ("dt",))
    assert max(abs(v) for v in errors.values()) > TOL


def test_a_psignifit_data_matrix_on_disk_fits_as_psignifit_fits_it(tmp_path):
    """A lab's psignifit data, as psignifit takes it (an array of height, n correct, n trials,
    saved by numpy.savetxt), read with the design it lacks: feeler's fit of the file and
    psignifit's of the array agree as the tables' fits do."""
    from feeler.psydata import MatrixDesign, read_trials

    task = Task(2)
    rng = np.random.default_rng(11)
    levels = np.array([0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 4.0])
    n = np.full(levels.size, 40)
    k = rng.binomial(n, task.p(levels, 1.8, 0.6, 0.03))
    matrix = np.column_stack([levels, k, n])
    np.savetxt(tmp_path / "observer.txt", matrix)
    trials = read_trials(tmp_path / "observer.txt", design=MatrixDesign(standard_um=0.0, speed_mm_s=20.0, nafc=True))
    row = threshold_table(fit_psychometric(trials, rng=np.random.default_rng(0), nafc=2,
                                           lapse_per="condition", pc=0.75)).iloc[0]
    assert row.subject == "observer" and row.design == "2AFC"
    cells = make_cells(trials, task).canonical()
    res = psignifit_fit(matrix[:, 0], matrix[:, 2], matrix[:, 1], Priors().resolve(cells), nafc=2)
    errors = _compare(row, grid_summary(res, nafc=2, pc=0.75), ("pse", "threshold"))
    bad = {k: f"{100 * v:.2f} %" for k, v in errors.items() if abs(v) > TOL}
    assert not bad, f"differences beyond {100 * TOL:g} % of the interval width: {bad}"
