"""M4: psychometric functions fitted to forced-choice data, with thresholds, slopes, PSEs,
goodness of fit and a verdict.

Pipeline: trial table → canonical cells → backend → row summaries and modes → checks
(goodness of fit, prior–data conflict, units, identifiability) → posterior ``DataTree``
with the thresholds table → FitResult (summary + verdict).

Model (:mod:`feeler.calib.psychometric.model.task`): per subject s and condition c, P = base(λ) + scale(λ)·Φ((x − m_sc)/σ_sc)
for the comparison design (P "comparison judged higher") or nAFC (P correct, guess 1/n);
binomial counts, or beta-binomial with concentration φ (``overdispersion``); priors
scaled to each condition's stimulus range (:mod:`feeler.calib.psychometric.model.priors`).

Backends:
- ``"exact"`` (default): each observer's posterior integrated on an adaptive grid;
  deterministic; ``all`` = the pooled trials.
- ``"laplace"``: per-observer mode + Gaussian approximation (approximate: warns when its
  bounds disagree with the exact posterior).
- ``"nuts"``: PyMC NUTS, hierarchical (``all`` = population mean, or the pooled trials)
  or separate (``hierarchical=False``).

Posterior variables: ``pse``, ``sigma``, ``dt`` (subject, condition), ``lapse``
(subject[, condition]), ``pse_all``, ``sigma_all``, ``dt_all`` (condition), ``lapse_all``,
plus the hierarchical model's hyper-parameters and ``phi``. Heights in µm.
"""
from __future__ import annotations

import json
import time
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from feeler.calib.fit import DiagnosticWarning, FitResult, make_result, posterior_from_draws
from feeler.calib.psychometric.outputs import checks
from feeler.calib.psychometric.backends import ApproximationWarning, row_draws, run_nuts, run_per_observer
from feeler.calib.psychometric.model.cells import POOLED, Cells, make_cells
from feeler.calib.psychometric.exact.grid import GridSpec
from feeler.calib.psychometric.independent import check_draw_counts, independent_result
from feeler.calib.psychometric.model.observer import LAPSE_PER
from feeler.calib.psychometric.model.priors import Priors, stimulus_ranges
from feeler.calib.psychometric.outputs.table import THRESHOLD_COLUMNS, table_csv, table_rows, threshold_table
from feeler.calib.psychometric.model.task import Task
from feeler.errors import ArgumentError
from feeler.rundir import prepare_out_dir

__all__ = ["fit_psychometric", "check_arguments", "threshold_table", "save_psychometric", "BACKENDS", "ESTIMANDS",
           "Priors", "THRESHOLD_COLUMNS", "with_problems", "ApproximationWarning", "LAPSE_PER"]

BACKENDS = ("exact", "laplace", "nuts")
ESTIMANDS = {"pooled": "pooled trials", "population": "population mean"}


def check_arguments(backend, chains, draws, tune, target_accept, lapse_per, all_estimand, hierarchical, pc, nafc):
    """The arguments of :func:`fit_psychometric` other than the data, checked (the command
    calls it before reading the data). Raises ArgumentError naming the first bad one."""
    if backend not in BACKENDS:
        raise ArgumentError("backend", backend, f"allowed: {', '.join(BACKENDS)}")
    for name, value, low in (("chains", chains, 1), ("draws", draws, 1), ("tune", tune, 0)):
        if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or value < low:
            raise ArgumentError(name, value, f"must be an integer >= {low}")
    check_draw_counts(chains, draws)
    if not 0.0 < float(target_accept) < 1.0:
        raise ArgumentError("target_accept", target_accept, "must be in (0, 1)")
    if lapse_per not in LAPSE_PER:
        raise ArgumentError("lapse", lapse_per, f"allowed: {', '.join(LAPSE_PER)}")
    if all_estimand is not None and all_estimand not in ESTIMANDS:
        raise ArgumentError("all", all_estimand, f"allowed: {', '.join(ESTIMANDS)}")
    if all_estimand == "population" and not (backend == "nuts" and hierarchical):
        raise ArgumentError("all", all_estimand, "a population mean needs the hierarchical model "
                                                 "(--backend nuts without --separate)")
    if pc is not None:
        Task(nafc).check_pc(pc)


def fit_psychometric(trials: pd.DataFrame, *, rng: np.random.Generator, backend: str = "exact",
                     hierarchical: bool = True, overdispersion: bool = False,
                     priors: Priors = Priors(), lapse_per: str = "subject", all_estimand: str | None = None,
                     nafc: int | None = None, pc: float | None = None, chains: int = 4, draws: int = 1000,
                     tune: int = 1000, target_accept: float = 0.99, progressbar: bool | None = False,
                     grid: GridSpec = GridSpec()) -> FitResult:
    """Fit M4 to a validated trial table (:func:`feeler.psydata.read_trials`).

    Args:
        trials: aggregated table (``n_comparison_higher``, or ``n_correct`` with ``nafc``);
            zero-trial rows contribute nothing; row order does not matter.
        rng: the seeded generator (draws, posterior predictive checks, NUTS seed).
        backend (str): "exact", "laplace" or "nuts" (only nuts uses ``hierarchical``).
        lapse_per (str): one lapse rate per "subject" or per "condition" (psignifit's).
        all_estimand (str | None): ``all`` = "pooled" trials or the "population" mean
            (hierarchical NUTS only); None: population for hierarchical NUTS, else pooled.
        nafc (int | None): number of alternatives for nAFC proportion-correct data.
        pc (float | None): proportion of the threshold column (default 0.75 for the
            comparison design, halfway from 1/n to 1 for nAFC).
        chains, draws, tune (int): draws per chain (exact and Laplace: independent draws,
            judged by their number, not by R-hat); at least 2 chains of 4 draws and
            400 draws in all (:func:`~feeler.calib.psychometric.independent.check_draw_counts`).
        target_accept (float): NUTS step-size target in (0, 1).
    Raises:
        ArgumentError: a bad argument (too few chains or draws), a table without trials, a hierarchical model with
            fewer than two subjects.
    """
    check_arguments(backend, chains, draws, tune, target_accept, lapse_per, all_estimand, hierarchical, pc, nafc)
    task = Task(nafc)
    pc = task.default_pc if pc is None else float(pc)
    cells = make_cells(trials, task).canonical()
    hier = backend == "nuts" and hierarchical
    estimand = all_estimand or ("population" if hier else "pooled")
    if hier and len(cells.subjects) < 2:
        raise ArgumentError("hierarchical", f"{len(cells.subjects)} subject",
                            "the hierarchical model needs at least 2 subjects with trials; "
                            "use --separate or --backend exact")
    resolved = priors.resolve(cells)
    start = time.perf_counter()
    if backend == "nuts":
        fitted = run_nuts(cells, resolved, hierarchical=hierarchical, pooled=estimand == "pooled",
                          lapse_per=lapse_per, overdispersion=overdispersion, rng=rng, chains=chains,
                          draws=draws, tune=tune, target_accept=target_accept, pc=pc, progressbar=progressbar)
        label = f"nuts ({'hierarchical' if hierarchical else 'separate'})"
    else:
        fitted = run_per_observer(cells, resolved, backend=backend, lapse_per=lapse_per,
                                  overdispersion=overdispersion, rng=rng, chains=chains, draws=draws,
                                  pc=pc, spec=grid, progressbar=progressbar)
        label = "exact (adaptive grid)" if backend == "exact" else "laplace (approximate)"
    rows, lead, problems = _rows_and_checks(cells, resolved, fitted, task, pc, label, ESTIMANDS[estimand],
                                            lapse_per, rng)
    problems = fitted.problems + problems
    seconds = time.perf_counter() - start
    out = dict(fitted.draws)
    if not task.is_nafc:
        out["dt"] = task.dt(out["sigma"], _per_cell(out["lapse"], out["sigma"].ndim))
        out["dt_all"] = task.dt(out["sigma_all"], _per_cell(out["lapse_all"], out["sigma_all"].ndim))
    attrs = {"backend": label, "all_estimand": ESTIMANDS[estimand], "pc": pc, "lapse_per": lapse_per,
             "thresholds_csv": table_csv(table_rows(rows)), "approximation_warnings": json.dumps(fitted.notes)}
    tree = _tree(out, fitted.sample_stats, cells, attrs, trials.attrs.get("comments", []))
    described = resolved.described(cells, hierarchical=hier, overdispersion=overdispersion)
    described["task"] = task.name
    described["all"] = f"'all' is the {ESTIMANDS[estimand]}"
    if backend == "nuts":
        result = make_result(tree, backend=label, priors=described, seconds=seconds)
    else:                                       # independent draws: R-hat does not apply, ESS = their number
        result = independent_result(tree, backend=label, priors=described, seconds=seconds)
    if fitted.notes:
        more = f" (and {len(fitted.notes) - 1} more)" if len(fitted.notes) > 1 else ""
        warnings.warn(f"Laplace is approximate and its tails disagree with the exact posterior: "
                      f"{fitted.notes[0]}{more}; use --backend exact", ApproximationWarning, stacklevel=2)
    return with_problems(result, problems, lead=lead)


def _per_cell(lapse: np.ndarray, ndim: int) -> np.ndarray:
    """Lapse draws broadcast against sigma (chain, draw, [subject,] condition)."""
    return lapse if lapse.ndim == ndim else lapse[..., None]


def _rows_and_checks(cells: Cells, r, fitted, task: Task, pc: float, label: str, estimand: str,
                     lapse_per: str, rng: np.random.Generator) -> tuple[list[dict], list[str], list[str]]:
    """(rows, the problems that lead the verdict: a likely slip that explains others, the
    other problems)."""
    lo, hi = stimulus_ranges(cells)
    problems = checks.straddle_problems(task, cells) + checks.unit_problems(
        np.concatenate([cells.x_um, cells.standard_um])) + checks.speed_problems([c[1:] for c in cells.conditions])
    rows, data = [], {}
    keys = sorted(fitted.stats, key=lambda k: (k[0] < 0, k[0], k[1]))
    row_rngs = dict(zip(keys, rng.spawn(len(keys))))
    pooled = cells.pooled()
    for o, c in keys:
        stats = fitted.stats[(o, c)]
        subject = POOLED if o < 0 else cells.subjects[o]
        name = f"{subject} [{cells.condition_label(c)}]"
        src = pooled if o < 0 else cells
        sel = (src.condition == c) & ((src.subject == o) if o >= 0 else True)
        x, n, k = src.x_um[sel], src.n[sel], src.k[sel]
        d = row_draws(fitted.draws, o, c, lapse_per)
        mp = None if fitted.maps is None else fitted.maps[o]
        point = _point(mp, c, lapse_per, stats)
        population = o < 0 and estimand == "population mean"
        dev, ppp = checks.gof(task, x, n, k, d, point, row_rngs[(o, c)]) if not population else (np.nan, np.nan)
        n_levels = int(np.unique(x).size)
        data[name] = (x, n, k)
        rows.append({"subject": subject, "estimand": estimand if o < 0 else "subject",
                     "standard_um": cells.conditions[c][0], "standard_speed_mm_s": cells.conditions[c][1],
                     "comparison_speed_mm_s": cells.conditions[c][2], "design": task.label,
                     "backend": label, "pc": pc, "stats": stats, "map": _map_row(task, point, pc, mp),
                     "n_levels": n_levels, "n_trials": int(n.sum()), "deviance": dev, "gof_p": ppp,
                     "gof_ok": bool(ppp >= checks.GOF_ALPHA) if np.isfinite(ppp) else None, "label": name,
                     "n_cells": int(x.size), "worst": checks.worst_cell(task, x, n, k, point)})
        problems += checks.level_problems(name, n_levels, x)
        if n_levels >= 2:
            what = "PSE" if not task.is_nafc else "location"
            problems += checks.bracket_problems(name, what, stats["pse"]["lb"], stats["pse"]["ub"], lo[c], hi[c])
            problems += checks.conflict_problems(name, c, r, d, levels_um=np.concatenate([cells.x_um, cells.standard_um]))
            if np.isfinite(dev):                    # not a population mean: the row's own cells
                problems += checks.drag_problems(name, task, x, n, k, point, what)
            if np.isfinite(dev) and not (o < 0 and len(cells.subjects) == 1):      # 'all' = the one subject
                spread = checks.spread_problems(name, task, x, n, k, dev, point["lapse"],
                                                standard_um=float(cells.conditions[c][0]))
                if not spread and n_levels >= checks.MIN_LEVELS:     # fewer: level_problems said it
                    spread = checks.interior_problems(name, task, x, n, k)
                problems += spread
        problems += checks.threshold_problems(name, task, pc, stats)
    if len(cells.subjects) == 1:                   # 'all' is the one subject: the same check
        first = {(rw["standard_um"], rw["standard_speed_mm_s"], rw["comparison_speed_mm_s"]): rw
                 for rw in rows if rw["subject"] != POOLED}
        for rw in rows:
            if rw["subject"] == POOLED and estimand == "pooled trials":
                twin = first[(rw["standard_um"], rw["standard_speed_mm_s"], rw["comparison_speed_mm_s"])]
                rw.update({k: twin[k] for k in ("deviance", "gof_p", "gof_ok")})
    gof = checks.gof_problems(rows)
    cut = checks.GOF_ALPHA / max(sum(np.isfinite(rw["gof_p"]) for rw in rows), 1)
    for rw in rows:
        if rw["gof_ok"] is not None:
            rw["gof_ok"] = bool(rw["gof_p"] >= cut)
    failing = [(rw["label"], *data[rw["label"]]) for rw in rows if rw["gof_ok"] is False]
    lead = checks.nafc_slip_problems(task, failing, cut, sum(rw["gof_ok"] is not None for rw in rows))
    return rows, lead, problems + gof


def _point(mp, c: int, lapse_per: str, stats: dict) -> dict:
    """The point estimate of a row: the MAP, or the posterior means without one."""
    if mp is None:
        return {"pse": stats["pse"]["mean"], "sigma": stats["sigma"]["mean"], "lapse": stats["lapse"]["mean"]}
    lam = mp["lapse"][c if lapse_per == "condition" else 0]
    return {"pse": float(mp["pse"][c]), "sigma": float(mp["sigma"][c]), "lapse": float(lam)}


def _map_row(task: Task, point: dict, pc: float, mp) -> dict:
    if mp is None:
        return {}
    m, s, lam = point["pse"], point["sigma"], point["lapse"]
    x = float(task.x_at(pc, m, s, lam))
    return {"pse": m, "sigma": s, "lapse": lam, "dt": float(task.dt(s, lam)),
            "threshold": x if np.isfinite(x) else np.inf, "slope": float(task.slope_at(pc, s, lam))}


def with_problems(result: FitResult, problems, *, lead=()) -> FitResult:
    """``result`` with extra verdict problems (failed when any), each issued as a warning;
    ``lead``: problems put first, before the sampler's (a likely slip that explains the rest)."""
    problems, lead = list(problems), list(lead)
    if not problems and not lead:
        return result
    for p in lead + problems:
        warnings.warn(f"posterior failed its diagnostics: {p}", DiagnosticWarning, stacklevel=2)
    verdict = replace(result.verdict, ok=False, problems=tuple(lead) + result.verdict.problems + tuple(problems))
    return replace(result, verdict=verdict)


_DIMS = {"pse": ["subject", "condition"], "sigma": ["subject", "condition"],
         "dt": ["subject", "condition"], "phi": ["subject"], "pse_all": ["condition"],
         "sigma_all": ["condition"], "dt_all": ["condition"], "mu_pse": ["condition"],
         "sd_pse": ["condition"], "mu_log_sigma": ["condition"], "sd_log_sigma": ["condition"]}


def _tree(out: dict, stats, cells: Cells, attrs: dict, comments: list):
    dims = {k: v for k, v in _DIMS.items() if k in out and np.ndim(out[k]) == 2 + len(v)}
    dims["lapse"] = ["subject", "condition"][:np.ndim(out["lapse"]) - 2]
    dims["lapse_all"] = ["condition"][:np.ndim(out["lapse_all"]) - 2]
    observed = {"x_um": cells.x_um, "n_trials": cells.n, "n_counted": cells.k,
                "subject_index": cells.subject, "condition_index": cells.condition}
    return posterior_from_draws(out, dims=dims, sample_stats=stats or None, observed=observed,
                                attrs=cells.attrs() | attrs | {"model": "M4 psychometric",
                                                               "units": "heights in um",
                                                               "data_comments": "\n".join(comments)})


def save_psychometric(result: FitResult, trials: pd.DataFrame, out_dir: str | Path, *,
                      force: bool, note: str = "", plots: bool = True) -> Path:
    """Write ``thresholds.csv`` (with ``# note`` lines first), the FitResult files and,
    with ``plots``, ``curves/*.png`` with ``curves/index.csv``."""
    names = ("thresholds.csv", "posterior.nc", "summary.csv", "verdict.json") + \
        (("curves/index.csv",) if plots else ())
    out = prepare_out_dir(out_dir, names, force=force)
    result.save(out, force=True)
    table = threshold_table(result, observed=None)
    with (out / "thresholds.csv").open("w", encoding="utf-8", newline="") as fh:
        for line in note.splitlines():
            fh.write(f"# {line}\n")
        fh.write(table_csv(table))
    if plots:
        from feeler.calib.psychometric.outputs.plots import write_curves
        write_curves(result, out / "curves", synthetic=bool(note))
    return out
