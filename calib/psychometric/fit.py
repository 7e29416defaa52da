"""M4: psychometric functions fitted to 2AFC data, with difference thresholds and PSEs.

Pipeline: trial table → cells → backend draws → posterior ``DataTree`` → FitResult
(summary + verdict) → :func:`threshold_table`.

Model (see :mod:`feeler.models.psychometric` for the DT convention): per subject s and
condition c, P(comparison judged higher) = λ_s/2 + (1 − λ_s)·Φ((x − PSE_sc)/σ_sc);
binomial counts, or beta-binomial with concentration φ (``overdispersion``).

Backends:
- ``"nuts"`` (default): PyMC NUTS, hierarchical (subjects' PSE and log σ from population
  normals; ``all`` = the population) or separate (``hierarchical=False``).
- ``"laplace"``: deterministic MAP + Laplace per subject; ``all`` is every trial fitted
  as one observer (complete pooling). Fast; for per-subject fits.

Posterior variables: ``pse``, ``sigma``, ``dt`` (subject, condition), ``lapse``
(subject), ``pse_all``, ``sigma_all``, ``dt_all`` (condition), ``lapse_all``, plus the
backend's hyper-parameters and ``phi``. Heights in µm.
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
from feeler.calib.psychometric.cells import POOLED, Cells, Priors, make_cells
from feeler.errors import ArgumentError
from feeler.models.psychometric import dt_from_sigma
from feeler.rundir import prepare_out_dir

__all__ = ["fit_psychometric", "threshold_table", "save_psychometric", "BACKENDS", "Priors",
           "THRESHOLD_COLUMNS", "with_problems"]

BACKENDS = ("nuts", "laplace")
THRESHOLD_COLUMNS = ("subject", "standard_speed_mm_s", "comparison_speed_mm_s", "pse_um",
                     "pse_lb_um", "pse_ub_um", "dt_um", "dt_lb_um", "dt_ub_um")


def fit_psychometric(trials: pd.DataFrame, *, rng: np.random.Generator, backend: str = "nuts",
                     hierarchical: bool = True, overdispersion: bool = False,
                     priors: Priors = Priors(), chains: int = 4, draws: int = 1000,
                     tune: int = 1000, target_accept: float = 0.99,
                     progressbar: bool = False) -> FitResult:
    """Fit M4 to a validated trial table (:func:`feeler.psydata.read_trials`).

    Args:
        trials: the 2AFC table; zero-trial rows contribute nothing. Its
            ``attrs["comments"]`` (e.g. "synthetic ...") go into the posterior's attrs.
        rng: the seeded generator (NUTS seed or Laplace draws come from it).
        backend (str): "nuts" or "laplace" (laplace ignores ``hierarchical``).
        chains, draws, tune (int): draws per chain (Laplace: independent draws).
        target_accept (float): NUTS step-size target in (0, 1); the default 0.99 avoids
            the rare divergences at the neck of the hierarchical sds with ~6 subjects.
    Returns:
        FitResult whose posterior carries the subjects and conditions in its attrs.
    """
    if backend not in BACKENDS:
        raise ArgumentError("backend", backend, f"allowed: {', '.join(BACKENDS)}")
    for name, value, low in (("chains", chains, 1), ("draws", draws, 1), ("tune", tune, 0)):
        if not isinstance(value, (int, np.integer)) or value < low:
            raise ArgumentError(name, value, f"must be an integer >= {low}")
    if not 0.0 < float(target_accept) < 1.0:
        raise ArgumentError("target_accept", target_accept, "must be in (0, 1)")
    cells = make_cells(trials)
    start = time.perf_counter()
    if backend == "nuts":
        from feeler.calib.psychometric.nuts import nuts_fit
        out, stats = nuts_fit(cells, priors, hierarchical=hierarchical, overdispersion=overdispersion,
                              rng=rng, chains=chains, draws=draws, tune=tune,
                              target_accept=target_accept, progressbar=progressbar)
        problems, label = [], f"nuts ({'hierarchical' if hierarchical else 'separate'})"
    else:
        out, problems = _laplace_all(cells, priors, overdispersion, rng, chains, draws)
        stats, label, hierarchical = {}, "laplace (per subject)", False
    out["dt"] = dt_from_sigma(out["sigma"], out["lapse"][..., None])
    out["dt_all"] = dt_from_sigma(out["sigma_all"], out["lapse_all"][..., None])
    tree = _tree(out, stats, cells, label, trials.attrs.get("comments", []))
    described = priors.described(hierarchical=hierarchical, overdispersion=overdispersion)
    result = make_result(tree, backend=label, priors=described, seconds=time.perf_counter() - start)
    return with_problems(result, problems)


def with_problems(result: FitResult, problems) -> FitResult:
    """``result`` with extra verdict problems (failed when any), each issued as a warning."""
    if not problems:
        return result
    for p in problems:
        warnings.warn(f"posterior failed its diagnostics: {p}", DiagnosticWarning, stacklevel=2)
    verdict = replace(result.verdict, ok=False, problems=result.verdict.problems + tuple(problems))
    return replace(result, verdict=verdict)


def _laplace_all(cells: Cells, priors, overdispersion, rng, chains, draws):
    from feeler.calib.psychometric.laplace import laplace_subject

    per, problems = [], []
    for i, name in enumerate(cells.subjects):
        d, p = laplace_subject(cells.select(cells.subject == i, (name,)), priors,
                               overdispersion=overdispersion, rng=rng, chains=chains, draws=draws)
        per.append(d)
        problems += p
    pooled, p = laplace_subject(cells.pooled(), priors, overdispersion=overdispersion, rng=rng,
                                chains=chains, draws=draws)
    problems += p
    out = {"pse": np.stack([d["pse"] for d in per], axis=2),
           "sigma": np.stack([d["sigma"] for d in per], axis=2),
           "lapse": np.stack([d["lapse"] for d in per], axis=2),
           "pse_all": pooled["pse"], "sigma_all": pooled["sigma"], "lapse_all": pooled["lapse"]}
    if overdispersion:
        out["phi"] = np.stack([d["phi"] for d in per], axis=2)
        out["phi_all"] = pooled["phi"]
    return out, problems


_DIMS = {"pse": ["subject", "condition"], "sigma": ["subject", "condition"],
         "dt": ["subject", "condition"], "lapse": ["subject"], "phi": ["subject"],
         "pse_all": ["condition"], "sigma_all": ["condition"], "dt_all": ["condition"],
         "mu_pse": ["condition"], "sd_pse": ["condition"], "mu_log_sigma": ["condition"],
         "sd_log_sigma": ["condition"]}


def _tree(out: dict, stats: dict, cells: Cells, label: str, comments: list):
    dims = {k: v for k, v in _DIMS.items() if k in out and np.ndim(out[k]) == 2 + len(v)}
    observed = {"x_um": cells.x_um, "n_trials": cells.n, "n_comparison_higher": cells.k}
    return posterior_from_draws(out, dims=dims, sample_stats=stats or None, observed=observed,
                                attrs=cells.attrs() | {"backend": label, "model": "M4 psychometric",
                                                       "units": "heights in um",
                                                       "data_comments": "\n".join(comments)})


def threshold_table(result: FitResult, *, observed: pd.DataFrame | None = None) -> pd.DataFrame:
    """PSE and DT (posterior mean and 95 % equal-tailed interval) per subject and condition.

    Args:
        result: an M4 FitResult (also after :func:`feeler.calib.fit.load`).
        observed: the trial table; when given, (subject, condition) pairs without any
            trial are left out (and ``all`` rows of conditions nobody was tested in).
    Returns:
        DataFrame with ``THRESHOLD_COLUMNS``; subject ``all`` rows hold the pooled estimate.
    """
    post = result.posterior["posterior"]
    subjects = json.loads(post.attrs["subjects"])
    conditions = json.loads(post.attrs["conditions"])
    has = None if observed is None else _has_trials(observed)
    rows = []
    for si, subject in enumerate(subjects + [POOLED]):
        pooled = subject == POOLED
        for ci, (_, v_std, v_cmp) in enumerate(conditions):
            if has is not None and (subject if not pooled else None, ci) not in has:
                continue
            pick = (lambda v: post[v + "_all"].values[..., ci]) if pooled else \
                (lambda v: post[v].values[..., si, ci])
            pse, dt = pick("pse").ravel(), pick("dt").ravel()
            rows.append((subject, v_std, v_cmp, pse.mean(), *np.quantile(pse, [0.025, 0.975]),
                         dt.mean(), *np.quantile(dt, [0.025, 0.975])))
    return pd.DataFrame(rows, columns=list(THRESHOLD_COLUMNS))


def _has_trials(trials: pd.DataFrame) -> set:
    cells = make_cells(trials)
    keep = cells.n > 0
    pairs = {(cells.subjects[s], c) for s, c in zip(cells.subject[keep], cells.condition[keep])}
    return pairs | {(None, c) for _, c in pairs}          # (None, c): anyone has trials in c


def save_psychometric(result: FitResult, trials: pd.DataFrame, out_dir: str | Path, *,
                      force: bool, note: str = "") -> Path:
    """Write ``thresholds.csv`` (with ``# note`` lines first) plus the FitResult files."""
    out = prepare_out_dir(out_dir, ("thresholds.csv", "posterior.nc", "summary.csv",
                                    "verdict.json"), force=force)
    result.save(out, force=True)
    table = threshold_table(result, observed=trials)
    with (out / "thresholds.csv").open("w", encoding="utf-8", newline="") as fh:
        for line in note.splitlines():
            fh.write(f"# {line}\n")
        table.to_csv(fh, index=False, float_format="%.6g", lineterminator="\n")
    return out
