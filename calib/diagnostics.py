"""Diagnostics of a posterior: the tidy summary table and the verdict.

Rules (DESIGN §6): a fit fails when any parameter has R-hat > 1.01 or bulk ESS < 400,
when the sampler reports divergent transitions, when an emcee chain is shorter than 50
integrated autocorrelation times, when a parameter piles against a hard prior bound, or
when more than 5 % of an entry's draws are not finite (fewer are left out of its summary).
Every problem is a one-line string naming the parameter; a failed verdict issues one
:class:`DiagnosticWarning` that lists them. Exact/conjugate backends store independent draws from the
exact posterior and go through the very same checks (they pass naturally).
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np
import pandas as pd

from feeler.calib.posterior import flat_draws

__all__ = ["Verdict", "DiagnosticWarning", "Thresholds", "summarize", "diagnose", "bound_problems", "repeated_rows",
           "SUMMARY_COLUMNS"]

SUMMARY_COLUMNS = ("name", "mean", "sd", "eti95_lb", "eti95_ub", "eti89_lb", "eti89_ub",
                   "r_hat", "ess_bulk", "ess_tail", "mcse_mean", "mcse_sd")


class DiagnosticWarning(UserWarning):
    """A posterior failed one of its diagnostics (the message names the parameter)."""


@dataclass(frozen=True)
class Verdict:
    """Whether a posterior may be used downstream.

    Attributes:
        ok (bool): True when no problem was found.
        problems (tuple[str, ...]): one line per problem, each naming the parameter.
    """
    ok: bool
    problems: tuple[str, ...] = ()

    def as_dict(self) -> dict:
        return {"ok": bool(self.ok), "problems": list(self.problems)}

    @classmethod
    def from_dict(cls, d: Mapping) -> "Verdict":
        return cls(ok=bool(d["ok"]), problems=tuple(str(p) for p in d["problems"]))


@dataclass(frozen=True)
class Thresholds:
    """Limits of the verdict (defaults from DESIGN §6)."""
    r_hat_max: float = 1.01
    ess_bulk_min: float = 400.0
    autocorr_times_min: float = 50.0
    bound_edge_fraction: float = 0.01   # width of the "edge" strip, fraction of the range
    bound_mass_max: float = 0.05        # posterior mass allowed inside that strip
    nonfinite_max: float = 0.05         # share of draws an entry may leave undefined (NaN)
    spread_of_prior_max: float = 0.7    # a posterior (log) spread above this share of the prior's: not pinned


def summarize(posterior) -> pd.DataFrame:
    """A row per scalar parameter entry with the columns of ``SUMMARY_COLUMNS``.

    Intervals are equal-tailed (ETI) 95 % and 89 %; R-hat is the rank-normalised split
    R-hat, ESS bulk/tail and MCSE as in ArviZ 1.x (Vehtari et al. 2021).
    """
    from feeler.calib import convergence as C

    draws = flat_draws(posterior)
    names = list(draws)
    funcs = {"r_hat": C.rhat, "ess_bulk": C.ess_bulk, "ess_tail": C.ess_tail,
             "mcse_mean": C.mcse_mean, "mcse_sd": C.mcse_sd}
    rows = []
    for name in names:
        flat = draws[name][np.isfinite(draws[name])]          # moments and intervals: every finite draw
        x = _finite_chains(draws[name])                        # R-hat, ESS, MCSE: equal chains
        if flat.size == 0:
            rows.append([name] + [np.nan] * (len(SUMMARY_COLUMNS) - 1))
            continue
        q = np.quantile(flat, [0.025, 0.975, 0.055, 0.945])
        with np.errstate(invalid="ignore", divide="ignore"):
            rest = [float(np.asarray(f(x), dtype=float)) for f in funcs.values()]
        rows.append([name, flat.mean(), flat.std(ddof=1) if flat.size > 1 else np.nan, *q, *rest])
    return pd.DataFrame(rows, columns=list(SUMMARY_COLUMNS))


def _finite_chains(x: np.ndarray) -> np.ndarray:
    """The finite draws of one entry ``x (ndarray[chain, draw])``, each chain cut to the
    shortest chain's count (so R-hat and ESS see equal chains); x itself when all are
    finite. A model whose derived quantity is undefined at some draws (the M2 decoder's
    line where its plates are not ordered) is summarised over the draws that define it;
    :func:`diagnose` fails the verdict when they are more than ``nonfinite_max``."""
    ok = np.isfinite(x)
    if ok.all():
        return x
    kept = [row[m] for row, m in zip(x, ok)]
    n = min(len(k) for k in kept)
    if n < 4:                                   # too short to compare chains: one chain of all
        return np.concatenate(kept)[None, :]
    return np.stack([k[:n] for k in kept])


def diagnose(posterior, summary: pd.DataFrame | None = None, *, backend: str,
             bounds: Mapping[str, tuple[float, float]] | None = None,
             thresholds: Thresholds = Thresholds(), checks: Sequence[str] = ()) -> Verdict:
    """Check a posterior and return its :class:`Verdict`; warn once per problem.

    Args:
        posterior: ArviZ ``DataTree`` (groups posterior and, for NUTS, sample_stats).
        summary: the table from :func:`summarize` (computed when omitted).
        backend (str): "exact", "nuts", "emcee", ...; "emcee" adds the autocorrelation
            check (chain length in stored draws ≥ 50 τ_int per parameter).
        bounds (dict[str, (lo, hi) | (lo, hi, "log")]): hard prior bounds of some
            parameters; a parameter with more than 5 % of its draws within 1 % of the
            range from a bound (of the log range for "log": a log-uniform prior) is
            flagged as piling against it.
        checks (list[str]): the model's own problems (identifiability, units, predictive
            checks), listed first. A parameter with no finite draw (the data do not
            define it; a check names why) is reported once instead of by R-hat and ESS;
            one with some (a derived quantity undefined at some draws) is summarised over
            the others, and the verdict fails when they are more than
            ``thresholds.nonfinite_max``.
    """
    summary = summarize(posterior) if summary is None else summary
    t = thresholds
    problems: list[str] = list(checks)
    draws = flat_draws(posterior)
    undefined = {n: float(np.mean(~np.isfinite(x))) for n, x in draws.items()}
    partial = [n for n, f in undefined.items() if t.nonfinite_max < f < 1.0]
    if partial:
        worst = max(undefined[n] for n in partial)
        problems.append(f"{_names(partial)}: up to {100 * worst:.0f} % of the posterior draws not finite "
                        f"(at most {100 * t.nonfinite_max:.0f} % may be; these data leave them undefined there)")
    undefined_all = [row.name for row in summary.itertuples(index=False) if not np.isfinite(row.mean)]
    if undefined_all:
        problems.append(f"{_names(undefined_all)}: no finite posterior draws (not defined by these data)")
    for row in summary.itertuples(index=False):
        if not np.isfinite(row.mean):
            continue
        if row.sd == 0 and np.ptp(draws[row.name][np.isfinite(draws[row.name])]) == 0:
            continue            # fixed by the model at every draw (two-mode's snap offset on a plate of step 0)
        if not np.isfinite(row.r_hat) or row.r_hat > t.r_hat_max:
            problems.append(f"{row.name}: R-hat {row.r_hat:.4f} > {t.r_hat_max}")
        if not np.isfinite(row.ess_bulk) or row.ess_bulk < t.ess_bulk_min:
            problems.append(f"{row.name}: bulk ESS {row.ess_bulk:.0f} < {t.ess_bulk_min:.0f}")
    problems += _divergences(posterior)
    if backend == "emcee":
        problems += _autocorr_problems(draws, t.autocorr_times_min)
    for name, (lo, hi, *scale) in (bounds or {}).items():
        problems += bound_problems(name, draws[name], lo, hi, t, *scale)
    if problems:
        more = f"; and {len(problems) - 8} more" if len(problems) > 8 else ""
        warnings.warn("posterior failed its diagnostics: " + "; ".join(problems[:8]) + more,
                      DiagnosticWarning, stacklevel=3)
    return Verdict(ok=not problems, problems=tuple(problems))


def _names(names: Sequence[str]) -> str:
    """Entry names joined, each vector's consecutive indices as one range:
    ``a, plate_sd_mm[0-3]`` for a, plate_sd_mm[0], ..., plate_sd_mm[3]."""
    out, runs = [], {}
    for name in names:
        base, _, idx = name.partition("[")
        if idx.endswith("]") and idx[:-1].isdigit():
            if base not in runs:
                runs[base] = []
                out.append(base)
            runs[base].append(int(idx[:-1]))
        else:
            out.append(name)
    parts = []
    for name in out:
        if name not in runs:
            parts.append(name)
            continue
        idx = runs[name]
        spans, start = [], idx[0]
        for prev, cur in zip(idx, idx[1:] + [None]):
            if cur != prev + 1:
                spans.append(f"{start}" if start == prev else f"{start}-{prev}")
                start = cur
        parts.append(f"{name}[{', '.join(spans)}]")
    return ", ".join(parts)


def _divergences(posterior) -> list[str]:
    if "sample_stats" not in posterior.children:
        return []
    stats = posterior["sample_stats"]
    if "diverging" not in stats.data_vars:
        return []
    n = int(np.asarray(stats["diverging"].values).sum())
    if n == 0:
        return []
    names = ", ".join(str(v) for v in posterior["posterior"].data_vars)
    return [f"all parameters ({names}): {n} divergent transitions"]


def _autocorr_problems(draws: Mapping[str, np.ndarray], times_min: float) -> list[str]:
    import logging

    from emcee.autocorr import integrated_time

    out = []
    log = logging.getLogger("emcee")
    level = log.level
    log.setLevel(logging.ERROR)       # quiet=True would log a warning per parameter
    try:
        draws = {name: _finite_chains(x) for name, x in draws.items() if np.isfinite(x).any()}
        taus = {name: float(integrated_time(x.T[:, :, None], quiet=True)[0])
                for name, x in draws.items()}          # x: (walker, step)
    finally:
        log.setLevel(level)
    for name, x in draws.items():
        n_steps, tau = x.shape[1], taus[name]
        if not np.isfinite(tau) or n_steps < times_min * tau:
            out.append(f"{name}: emcee chain of {n_steps} steps is shorter than "
                       f"{times_min:.0f} autocorrelation times (tau = {tau:.1f} steps)")
    return out


def repeated_rows(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows equal to an earlier row of ``rows (ndarray[n, m])``, as (their indices,
    ndarray[k]; the index of every row's first occurrence, ndarray[n]): the copies of a
    data file appended to itself."""
    _, first, inverse = np.unique(np.asarray(rows), axis=0, return_index=True, return_inverse=True)
    earlier = first[np.ravel(inverse)]
    return np.flatnonzero(earlier != np.arange(len(earlier))), earlier


def bound_problems(name: str, x: np.ndarray, lo: float, hi: float, t: Thresholds, scale: str = "linear") -> list[str]:
    """Piling against a hard bound: more than ``bound_mass_max`` of the draws inside the
    edge strip, ``bound_edge_fraction`` of the range measured where the prior is uniform
    (``scale`` "log" for a log-uniform parameter such as a window τ). A posterior equal
    to its prior puts ``bound_edge_fraction`` there, five times less than the limit; on a
    linear strip a log-uniform prior alone put 5.8 % of its mass at the lower end of
    0.5–10 s and a fit that learnt nothing about τ near it "piled"."""
    f = np.log if scale == "log" else (lambda v: v)
    u, ulo, uhi = f(np.asarray(x, float)), f(lo), f(hi)
    edge = t.bound_edge_fraction * (uhi - ulo)
    out = []
    for side, near, end in (("lower", u <= ulo + edge, ulo + edge), ("upper", u >= uhi - edge, uhi - edge)):
        frac = float(np.mean(near))
        if frac > t.bound_mass_max:
            bound = lo if side == "lower" else hi
            strip = (f"{'below' if side == 'lower' else 'above'} {float(np.exp(end)):.3g}" if scale == "log"
                     else f"within {edge:.3g} of it")
            out.append(f"{name}: posterior piles against its {side} prior bound {bound:g} "
                       f"({100 * frac:.0f} % of draws {strip})")
    return out
