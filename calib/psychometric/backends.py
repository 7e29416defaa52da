"""Run one M4 backend over the observers and hand back draws, row summaries and modes.

Observers are the subjects plus ``all``: the pooled trials (a separate observer) or, for
the hierarchical model, the population. With a single subject the pooled ``all`` *is*
that subject, and is copied from it.

Row summaries come from the exact grid (``exact``) or from the draws (``laplace``,
``nuts``); the MAP (the mode over the linear parameters m, σ, λ, as psignifit reports it)
is computed for every non-hierarchical fit, whatever the backend.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from feeler.calib.progress import progress
from feeler.calib.psychometric.model.cells import POOLED, Cells
from feeler.calib.psychometric.outputs.draws import draw_row_stats
from feeler.calib.psychometric.exact.grid import L_MIN, GridSpec, observer_grid
from feeler.calib.psychometric.exact.stats import grid_draws, grid_row_stats
from feeler.calib.psychometric.model.mode import maximise
from feeler.calib.psychometric.model.observer import Observer

__all__ = ["Fitted", "run_per_observer", "run_nuts", "natural_map", "ApproximationWarning",
           "TAIL_TOLERANCE"]

#: Laplace bounds further than this fraction of the exact 95 % interval width are flagged
TAIL_TOLERANCE = 0.1


class ApproximationWarning(UserWarning):
    """An approximate backend (Laplace) disagrees with the exact posterior."""


@dataclass
class Fitted:
    """A backend's output before tables and checks.

    Attributes:
        draws (dict[str, ndarray[chain, draw, ...]]): the DataTree variables.
        stats (dict[(int, int), dict]): row summaries keyed by (observer, condition);
            observer -1 is ``all``.
        maps (dict[int, dict] | None): natural-parameter modes per observer.
        problems, notes (list[str]): verdict problems; approximation warnings.
    """
    draws: dict
    stats: dict
    maps: dict | None
    problems: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    sample_stats: dict | None = None


def natural_map(obs: Observer, start: np.ndarray) -> dict:
    """The mode over (m, σ, λ[, φ]): ``pse``, ``sigma`` (n_cond), ``lapse`` (n_lapse)."""
    lower = np.full(start.size, -np.inf)
    lower[2 * obs.n_cond:2 * obs.n_cond + obs.n_lapse] = L_MIN
    theta, _, _ = maximise(obs.log_natural, start, lower=lower)
    out = obs.unpack(theta)
    return {"pse": out["pse"], "sigma": out["sigma"], "lapse": out["lapse"]}


def _observers(cells: Cells, pooled: bool) -> list[tuple[int, str, Cells]]:
    out = [(i, s, cells.select(cells.subject == i, (s,))) for i, s in enumerate(cells.subjects)]
    if pooled and len(cells.subjects) > 1:
        out.append((-1, POOLED, cells.pooled()))
    return out


def _has(cells: Cells, o: int, c: int) -> bool:
    sel = cells.condition == c
    return bool(np.any(sel if o < 0 else sel & (cells.subject == o)))


def run_per_observer(cells: Cells, r, *, backend: str, lapse_per: str, overdispersion: bool,
                     rng: np.random.Generator, chains: int, draws: int, pc: float,
                     spec: GridSpec = GridSpec(), progressbar: bool | None = False) -> Fitted:
    """Exact grid or Laplace, observer by observer (see the module doc)."""
    from feeler.calib.psychometric.laplace import laplace_observer

    obs_list = _observers(cells, pooled=True)
    rngs = rng.spawn(len(obs_list))
    n = chains * draws
    per, stats, maps, problems, notes = {}, {}, {}, [], []
    for (o, label, oc), g_rng in progress(list(zip(obs_list, rngs)), desc=f"M4 {backend}",
                                          enabled=progressbar):
        obs = Observer(oc, r, lapse_per=lapse_per, overdispersion=overdispersion)
        grid = observer_grid(obs, spec)
        problems += [f"{label}: {a}" for a in grid.uncontained]
        rows = [c for c in range(len(cells.conditions)) if _has(cells, o, c)]
        exact_stats = {c: grid_row_stats(grid, c, pc) for c in rows}
        if backend == "exact":
            per[o] = grid_draws(grid, g_rng, n)
            stats |= {(o, c): s for c, s in exact_stats.items()}
        else:
            per[o], p = laplace_observer(obs, rng=g_rng, n=n)
            problems += p
            for c in rows:
                stats[(o, c)] = draw_row_stats(cells.task, per[o]["pse"][:, c], per[o]["sigma"][:, c],
                                               per[o]["lapse"][:, c if lapse_per == "condition" else 0], pc)
                notes += _tail_notes(f"{label} [{cells.condition_label(c)}]", stats[(o, c)], exact_stats[c])
        maps[o] = natural_map(obs, grid.mode)
    if -1 not in per:                                   # one subject: 'all' is that subject
        per[-1], maps[-1] = per[0], maps[0]
        stats |= {(-1, c): s for (o, c), s in list(stats.items()) if o == 0}
    return Fitted(_assemble(per, len(cells.subjects), chains, draws), stats, maps, problems, notes)


def _tail_notes(label: str, approx: dict, exact: dict) -> list[str]:
    out = []
    for q in ("pse", "dt", "threshold"):
        width = exact[q]["ub"] - exact[q]["lb"]
        if not np.isfinite(width) or width <= 0:
            continue
        for side in ("lb", "ub"):
            if abs(approx[q][side] - exact[q][side]) > TAIL_TOLERANCE * width:
                out.append(f"{label}: Laplace {q} {'lower' if side == 'lb' else 'upper'} bound "
                           f"{approx[q][side]:.3g} µm vs exact {exact[q][side]:.3g} µm")
    return out


def _assemble(per: dict, n_sub: int, chains: int, draws: int) -> dict:
    def shaped(v):
        return v.reshape((chains, draws) + v.shape[1:])
    subs = [per[i] for i in range(n_sub)]
    out = {name: np.stack([shaped(d[name]) for d in subs], axis=2) for name in ("pse", "sigma")}
    lap = np.stack([shaped(d["lapse"]) for d in subs], axis=2)
    out["lapse"] = lap[..., 0] if lap.shape[-1] == 1 and per[-1]["lapse"].shape[-1] == 1 else lap
    out |= {"pse_all": shaped(per[-1]["pse"]), "sigma_all": shaped(per[-1]["sigma"])}
    la = shaped(per[-1]["lapse"])
    out["lapse_all"] = la[..., 0] if la.shape[-1] == 1 else la
    if "phi" in per[0]:
        out["phi"] = np.stack([shaped(d["phi"]) for d in subs], axis=2)
        out["phi_all"] = shaped(per[-1]["phi"])
    return out


def run_nuts(cells: Cells, r, *, hierarchical: bool, pooled: bool, lapse_per: str, overdispersion: bool,
             rng: np.random.Generator, chains: int, draws: int, tune: int, target_accept: float,
             pc: float, progressbar: bool | None) -> Fitted:
    """PyMC NUTS; summaries from the draws, modes for the separate model."""
    from feeler.calib.psychometric.nuts import nuts_fit

    one = len(cells.subjects) == 1
    out, sample_stats = nuts_fit(cells, r, hierarchical=hierarchical, pooled=pooled and not one,
                                 lapse_per=lapse_per, overdispersion=overdispersion, rng=rng,
                                 chains=chains, draws=draws, tune=tune, target_accept=target_accept,
                                 progressbar=progressbar)          # None: a bar on a terminal, lines off it
    if one and pooled:                                  # 'all' is the one subject
        out |= {f"{v}_all": out[v][:, :, 0] for v in ("pse", "sigma", "lapse", "phi") if v in out}
    stats, maps = {}, None if hierarchical else {}
    for o in list(range(len(cells.subjects))) + [-1]:
        for c in range(len(cells.conditions)):
            if _has(cells, o, c):
                d = row_draws(out, o, c, lapse_per)
                stats[(o, c)] = draw_row_stats(cells.task, d["pse"], d["sigma"], d["lapse"], pc)
        if maps is not None:
            oc = cells.pooled() if o < 0 else cells.select(cells.subject == o, (cells.subjects[o],))
            obs = Observer(oc, r, lapse_per=lapse_per, overdispersion=overdispersion)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                mode, _, _ = maximise(obs.log_post, obs.start())
            maps[o] = natural_map(obs, mode)
    return Fitted(out, stats, maps, sample_stats=sample_stats)


def row_draws(draws: dict, o: int, c: int, lapse_per: str) -> dict:
    """Flat draws of one row: ``pse``, ``sigma``, ``lapse`` and ``phi`` (or None)."""
    suffix = "_all" if o < 0 else ""
    pick = (lambda v: v[..., c]) if o < 0 else (lambda v: v[:, :, o, c])
    lap = draws["lapse" + suffix]
    if o >= 0:
        lap = lap[:, :, o]
    if lap.ndim == 3:
        lap = lap[..., c]
    phi = draws.get("phi" + suffix)
    if phi is not None and o >= 0:
        phi = phi[:, :, o]
    return {"pse": pick(draws["pse" + suffix]).ravel(), "sigma": pick(draws["sigma" + suffix]).ravel(),
            "lapse": lap.ravel(), "phi": None if phi is None else phi.ravel()}
