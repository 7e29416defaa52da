"""Exact M4 backend: the posterior of each observer by numerical integration on an
adaptive grid.

Given the lapse λ (and φ) the conditions of an observer are independent, so the posterior
of an observer with C conditions is held as C four-dimensional grids [lapse node, φ node,
log σ node, location node] on uniform axes in the unconstrained coordinates of
:mod:`feeler.calib.psychometric.model.observer` (l = logit B, f = log φ, s = log σ, m); without overdispersion the φ axis
has one node.

- **Placement**: each axis spans the range where the log posterior along it, through
  the mode, stays within ``edge_log`` − 3.5 of the peak (stretched by the ratio of marginal to
  conditional sd from the Hessian); then it **adapts**: a side whose marginal at the edge node is above e^``edge_log`` of its peak
  is pushed out to where a parabola through the last nodes of its log marginal reaches
  ``edge_log`` − 3.5, and an axis whose mass sits on less than a third of its nodes is
  shrunk onto that mass, until neither happens (``max_rounds``).
- A lapse shared by a subject's conditions (and φ) is integrated once per observer:
  weight(l, f) ∝ prior(l, f)·Π_c Z_c(l, f), Z_c the integral of condition c over its
  (s, m) plane.

Summaries are quadratures on the grid (:mod:`feeler.calib.psychometric.exact.stats`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import expit, gammaln, ndtr

from feeler.calib.psychometric.model.mode import gradient, hessian, maximise
from feeler.calib.psychometric.model.observer import Observer, lapse_logit_prior
from feeler.calib.psychometric.exact.quadrature import logsumexp
from feeler.models.psychometric import LAPSE_MAX

__all__ = ["GridSpec", "ObserverGrid", "observer_grid", "observer_mode"]

L_MIN, L_MAX = -30.0, 20.0      # logit B stays here (B from 1e-13 to 1 − 2e-9)


@dataclass(frozen=True)
class GridSpec:
    """Nodes per axis and the adaptation rules of the exact backend."""
    n_pse: int = 32
    n_s: int = 32
    n_l: int = 24
    n_f: int = 8
    edge_log: float = -11.5
    max_rounds: int = 8


@dataclass
class ObserverGrid:
    """The posterior of one observer on its grid.

    Attributes:
        obs: the :class:`Observer`.
        axes (list[dict[str, ndarray]]): per condition the ``l``, ``f``, ``s``, ``m`` nodes.
        log_mass (list[ndarray[L, F, S, M]]): per condition the log posterior mass of
            each node, joint with the observer's shared lapse/φ (sums to 1 per condition).
        mode (ndarray[n_par]): the mode of the θ density.
        uncontained (list[str]): axes whose posterior the grid could not contain or
            resolve (one sentence each).
    """
    obs: Observer
    axes: list
    log_mass: list
    mode: np.ndarray
    uncontained: list


def observer_mode(obs: Observer) -> tuple[np.ndarray, np.ndarray | None, str]:
    """(mode of the θ density, the Hessian there, problem text or ""): the better of the
    climbs from the prior centre and from the data (they differ when prior and data
    disagree, e.g. heights in mm under priors set in µm)."""
    best = None
    for start in (obs.start(), obs.data_start()):
        found = maximise(obs.log_post, start)
        value = float(obs.log_post(found[0][None])[0])
        if best is None or value > best[0]:
            best = (value, found)
    mode, ok, msg = best[1]
    h = hessian(obs.log_post, mode)
    grad = float(np.linalg.norm(gradient(obs.log_post, mode)))
    return mode, h, "" if ok or grad < 1e-3 else f"mode search did not converge (|gradient| {grad:.2g}: {msg})"


def _extents(obs: Observer, mode: np.ndarray, h: np.ndarray, spec: GridSpec) -> tuple[np.ndarray, np.ndarray]:
    """How far below and above the mode each coordinate's marginal keeps mass above
    e^edge_log: the log posterior along each axis through the mode, stepped in
    conditional sds, stretched by the marginal/conditional sd ratio of the Hessian."""
    n = mode.size
    r = obs.priors
    prior_sd = np.concatenate([r.pse_sd, np.full(obs.n_cond, r.log_sigma_sd), np.full(obs.n_lapse, 2.0),
                               [r.log_phi_sd] if obs.overdispersion else []])
    neg = -0.5 * (h + h.T)
    try:
        cov = np.linalg.inv(neg)
        ok = np.all(np.linalg.eigvalsh(neg) > 0)
    except np.linalg.LinAlgError:
        ok = False
    cond_sd = 1.0 / np.sqrt(np.diag(neg)) if np.all(np.diag(neg) > 0) else prior_sd
    ratio = np.sqrt(np.diag(cov) * np.diag(neg)) if ok else np.ones(n)
    cond_sd = np.where(np.isfinite(cond_sd) & (cond_sd > 0), cond_sd, prior_sd)
    ratio = np.where(np.isfinite(ratio) & (ratio >= 1), ratio, 1.0)
    steps = np.arange(1, 13, dtype=float)
    pts = mode + (np.concatenate([-steps, steps])[:, None, None] * np.eye(n)[None] * cond_sd)
    drop = obs.log_post(mode[None])[0] - obs.log_post(pts.reshape(-1, n)).reshape(2, steps.size, n)
    need = -spec.edge_log + 3.5
    out = []
    for side in range(2):
        hit = drop[side] >= need                                  # (steps, n)
        first = np.where(hit.any(axis=0), steps[np.argmax(hit, axis=0)], steps[-1])
        out.append(1.1 * first * ratio * cond_sd)
    return out[0], out[1]


def _initial_axes(obs: Observer, mode, h, spec: GridSpec) -> list[dict]:
    below, above = _extents(obs, mode, h, spec)
    c_n = obs.n_cond

    def span(i, n, lo=-np.inf, hi=np.inf):
        return np.linspace(max(mode[i] - below[i], lo), min(mode[i] + above[i], hi), n)

    f = span(2 * c_n + obs.n_lapse, spec.n_f) if obs.overdispersion else np.zeros(1)
    lapse_i = [2 * c_n + (c if obs.lapse_per == "condition" else 0) for c in range(c_n)]
    shared_l = span(lapse_i[0], spec.n_l, L_MIN, L_MAX)
    return [{"l": shared_l if obs.lapse_per == "subject" else span(lapse_i[c], spec.n_l, L_MIN, L_MAX),
             "f": f, "s": span(c_n + c, spec.n_s), "m": span(c, spec.n_pse)} for c in range(c_n)]


def _log_joint(obs: Observer, c: int, ax: dict) -> np.ndarray:
    """log likelihood + per-condition priors of condition c on its grid → (L, F, S, M)."""
    cells, r = obs.cells, obs.priors
    sel = cells.condition == c
    x, n, k = cells.x_um[sel], cells.n[sel], cells.k[sel]
    z = (x[None, None, :] - ax["m"][None, :, None]) * np.exp(-ax["s"])[:, None, None]   # (S, M, cells)
    up, down = ndtr(z), ndtr(-z)
    base, scale, rest = cells.task.base_scale_rest(LAPSE_MAX * expit(ax["l"]))
    out = np.empty((ax["l"].size, ax["f"].size, ax["s"].size, ax["m"].size))
    phi = np.exp(ax["f"])[:, None, None, None]
    phi_part = np.sum(gammaln(n + phi[:, :, :, 0][..., None]) - gammaln(phi[:, :, :, 0][..., None]), axis=-1) \
        if obs.overdispersion else 0.0
    with np.errstate(divide="ignore"):
        for i in range(ax["l"].size):
            p, q = base[i] + scale[i] * up, rest[i] + scale[i] * down
            if obs.overdispersion:     # betaln pair with p + q = 1: the φ-only part apart
                a, b = phi * p, phi * q
                out[i] = np.sum(gammaln(k + a) - gammaln(a) + gammaln(n - k + b) - gammaln(b), axis=-1) - phi_part
            else:
                out[i, 0] = np.log(p) @ k + np.log(q) @ (n - k)
    out += (-0.5 * ((ax["m"] - r.pse_mean[c]) / r.pse_sd[c]) ** 2)[None, None, None, :]
    out += (-0.5 * ((ax["s"] - r.log_sigma_mean[c]) / r.log_sigma_sd) ** 2)[None, None, :, None]
    if obs.lapse_per == "condition":
        out += lapse_logit_prior(ax["l"], r.lapse_a, r.lapse_b)[:, None, None, None]
    return np.where(np.isfinite(out), out, -np.inf)


def _normalised(obs: Observer, axes: list, logs: list) -> list:
    """Per-condition log joints → log masses (the shared lapse/φ integrated once)."""
    shared = (0, 1) if obs.lapse_per == "subject" else (1,)
    inner = tuple(a for a in range(4) if a not in shared)
    log_z = [logsumexp(a, axis=inner, keepdims=True) for a in logs]
    log_w = np.sum(log_z, axis=0)
    r = obs.priors
    if obs.lapse_per == "subject":
        log_w = log_w + lapse_logit_prior(axes[0]["l"], r.lapse_a, r.lapse_b)[:, None, None, None]
    if obs.overdispersion:
        log_w = log_w + (-0.5 * ((axes[0]["f"] - r.log_phi_mean) / r.log_phi_sd) ** 2)[None, :, None, None]
    log_w = log_w - logsumexp(log_w)
    return [a - z + log_w for a, z in zip(logs, log_z)]


def _reach(p: np.ndarray, step: float, target: float) -> float:
    """Distance beyond the last node of the log profile ``p`` (ascending towards that
    node's side) at which a parabola through its last three nodes falls to ``target``;
    a straight line when the parabola does not fall."""
    d1 = (p[-1] - p[-3]) / (2 * step)
    d2 = (p[-1] - 2 * p[-2] + p[-3]) / step ** 2
    need = p[-1] - target
    if d2 < 0:
        disc = d1 * d1 + 2 * (-d2) * need
        return float((d1 + np.sqrt(disc)) / (-d2)) if disc > 0 else np.inf
    return float(need / -d1) if d1 < 0 else np.inf


def _adapt(nodes: np.ndarray, profile: np.ndarray, spec: GridSpec, lo=-np.inf, hi=np.inf):
    """New nodes for one axis from its log marginal ``profile``, or None when it fits.

    A side whose edge is above ``edge_log`` is pushed out to where the edge's parabola
    reaches ``edge_log`` − 3.5 (between a quarter and twice the span); an axis whose mass
    sits on less than a third of its nodes is shrunk onto that mass."""
    p = profile - np.max(profile)
    width, step = nodes[-1] - nodes[0], nodes[1] - nodes[0]
    a, b = nodes[0], nodes[-1]
    target = spec.edge_log - 3.5
    if p[0] > spec.edge_log and a > lo:
        a = max(a - float(np.clip(_reach(p[::-1], step, target), 0.25 * width, 2 * width)), lo)
    if p[-1] > spec.edge_log and b < hi:
        b = min(b + float(np.clip(_reach(p, step, target), 0.25 * width, 2 * width)), hi)
    if (a, b) == (nodes[0], nodes[-1]):
        inside = np.flatnonzero(p > spec.edge_log)
        if inside.size >= max(nodes.size // 3, 2):
            return None
        first, last = nodes[max(inside[0] - 1, 0)], nodes[min(inside[-1] + 1, nodes.size - 1)]
        pad = max(0.15 * (last - first), step)
        a, b = max(first - pad, nodes[0]), min(last + pad, nodes[-1])
        if b - a >= 0.9 * width:
            return None
    return np.linspace(a, b, nodes.size)


def observer_grid(obs: Observer, spec: GridSpec = GridSpec()) -> ObserverGrid:
    """Integrate one observer's posterior on an adaptive grid (see the module doc)."""
    mode, h, _ = observer_mode(obs)
    axes = _initial_axes(obs, mode, h, spec)
    logs = [_log_joint(obs, c, ax) for c, ax in enumerate(axes)]
    for _ in range(spec.max_rounds):
        log_mass = _normalised(obs, axes, logs)
        changed = _adapt_all(obs, axes, log_mass, spec)
        if not changed:
            break
        logs = [_log_joint(obs, c, ax) if c in changed else old for c, (ax, old) in enumerate(zip(axes, logs))]
    log_mass = _normalised(obs, axes, logs)
    uncontained = _edges(obs, axes, log_mass, spec)
    return ObserverGrid(obs, axes, log_mass, mode, uncontained)


def _profiles(log_mass: np.ndarray) -> dict:
    names = ("l", "f", "s", "m")
    return {n: logsumexp(log_mass, axis=tuple(a for a in range(4) if a != i)) for i, n in enumerate(names)}


def _adapt_all(obs: Observer, axes: list, log_mass: list, spec: GridSpec) -> set:
    """Adapt every axis in place; returns the conditions whose grid changed."""
    changed = set()
    profiles = [_profiles(lm) for lm in log_mass]
    for c, (ax, prof) in enumerate(zip(axes, profiles)):
        for name in ("s", "m") + (("l",) if obs.lapse_per == "condition" else ()):
            lo, hi = (L_MIN, L_MAX) if name == "l" else (-np.inf, np.inf)
            new = _adapt(ax[name], prof[name], spec, lo, hi)
            if new is not None:
                ax[name] = new
                changed.add(c)
    shared = [("f", -np.inf, np.inf)] if obs.overdispersion else []
    if obs.lapse_per == "subject":
        shared.append(("l", L_MIN, L_MAX))
    for name, lo, hi in shared:
        new = _adapt(axes[0][name], profiles[0][name], spec, lo, hi)
        if new is not None:
            for ax in axes:
                ax[name] = new
            changed |= set(range(len(axes)))
    return changed


def _edges(obs: Observer, axes: list, log_mass: list, spec: GridSpec) -> list[str]:
    """Axes whose marginal is still above the edge threshold at a free edge."""
    out = []
    for c, (ax, lm) in enumerate(zip(axes, log_mass)):
        prof = _profiles(lm)
        for name, label in (("m", "location"), ("s", "log sigma"), ("l", "lapse"), ("f", "log phi")):
            if name == "f" and not obs.overdispersion:
                continue
            p = prof[name] - np.max(prof[name])
            lo_free = not (name == "l" and ax[name][0] <= L_MIN)
            hi_free = not (name == "l" and ax[name][-1] >= L_MAX)
            where = f"the posterior of the {label} [{obs.cells.condition_label(c)}]"
            if (p[0] > spec.edge_log and lo_free) or (p[-1] > spec.edge_log and hi_free):
                out.append(f"{where} is not contained by the grid: the data do not pin it down")
            elif np.max(np.exp(p)) > 0.5 * np.sum(np.exp(p)):
                out.append(f"{where} is not resolved by the grid (half its mass on one node): several modes?")
    return out
