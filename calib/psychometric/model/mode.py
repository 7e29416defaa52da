"""Posterior modes of the deterministic M4 backends: trust-region Newton, polished to 1e-10.

Every function takes a *batched* objective ``f(theta (B, n)) -> (B,)`` so a gradient or
a Hessian by central differences is one call of ``f`` on all stencil points.

The mode is polished by Newton steps until a step moves no parameter by more than
:data:`MODE_XTOL` (relative): a quasi-Newton stop leaves the mode uncertain at ~10⁻⁴,
which would let the summation order of the likelihood move the result by that much.
"""
from __future__ import annotations

import numpy as np

__all__ = ["gradient", "hessian", "newton_polish", "maximise", "MODE_XTOL"]

#: relative step size under which the Newton polish of the mode stops
MODE_XTOL = 1e-10


def gradient(f, x: np.ndarray, step: float = 1e-5) -> np.ndarray:
    """Central-difference gradient of a batched scalar function at ``x (n,)`` → (n,)."""
    n = x.size
    h = step * np.maximum(1.0, np.abs(x))
    pts = np.concatenate([x + np.diag(h), x - np.diag(h)])
    v = f(pts)
    return (v[:n] - v[n:]) / (2 * h)


def hessian(f, x: np.ndarray, step: float = 1e-4) -> np.ndarray:
    """Central-difference Hessian of a batched scalar function at ``x (n,)`` → (n, n)."""
    n = x.size
    h = step * np.maximum(1.0, np.abs(x))
    iu, ju = np.triu_indices(n)
    e = np.eye(n) * h
    ei, ej = e[iu], e[ju]
    pts = np.concatenate([x + ei + ej, x + ei - ej, x - ei + ej, x - ei - ej])
    v = f(pts).reshape(4, -1)
    vals = (v[0] - v[1] - v[2] + v[3]) / (4 * h[iu] * h[ju])
    out = np.empty((n, n))
    out[iu, ju] = vals
    out[ju, iu] = vals
    return out


def newton_polish(f, x: np.ndarray, *, max_steps: int = 30) -> tuple[np.ndarray, bool]:
    """Maximise a batched function ``f``, concave near ``x``, by damped Newton steps.

    Returns ``(x, converged)``: converged when the last full step moved every coordinate
    by less than :data:`MODE_XTOL` · max(1, |x|). A step that does not increase ``f``
    (beyond rounding) is halved up to 30 times; a Hessian that is not negative definite
    ends the polish unconverged, at the best point so far.
    """
    fx = float(f(x[None])[0])
    for _ in range(max_steps):
        g, h = gradient(f, x), hessian(f, x)
        try:
            np.linalg.cholesky(-0.5 * (h + h.T))
            step = np.linalg.solve(-h, g)
        except np.linalg.LinAlgError:
            return x, False
        if np.all(np.abs(step) <= MODE_XTOL * np.maximum(1.0, np.abs(x))):
            return x + step, True
        tol = 1e-12 * max(1.0, abs(fx))
        for _ in range(30):
            f_new = float(f((x + step)[None])[0])
            if f_new >= fx - tol:
                break
            step = 0.5 * step
        else:
            return x, False
        x, fx = x + step, max(f_new, fx)
    return x, False


def maximise(f, x0: np.ndarray, *, lower: np.ndarray | None = None,
             max_iter: int = 200, radius: float = 2.0) -> tuple[np.ndarray, bool, str]:
    """The maximum of a batched function by trust-region Newton steps, then the polish.

    Where the Hessian is not negative definite the step uses |eigenvalues| (floored), so
    it still climbs; every step is at most ``radius`` long and is halved until ``f``
    increases.

    Args:
        f: batched objective, (B, n) → (B,); -inf where undefined.
        x0 (ndarray[n]): start.
        lower (ndarray[n] | None): lower bounds (-inf: none); a coordinate that reaches
            its bound stays there and is not polished.
    Returns:
        (x, converged, message): converged when the Newton polish reached MODE_XTOL.
    """
    lower = np.full(x0.size, -np.inf) if lower is None else np.asarray(lower, float)
    x = np.maximum(np.asarray(x0, float), lower)
    fx = float(f(x[None])[0])
    if not np.isfinite(fx):
        return x, False, "objective not finite at the start"
    for _ in range(max_iter):
        g, h = gradient(f, x), hessian(f, x)
        if not (np.all(np.isfinite(g)) and np.all(np.isfinite(h))):
            return x, False, "gradient not finite"
        evals, evecs = np.linalg.eigh(-0.5 * (h + h.T))
        step = evecs @ ((evecs.T @ g) / np.maximum(np.abs(evals), 1e-8 * max(1.0, np.abs(evals).max())))
        norm = np.linalg.norm(step)
        if norm > radius:
            step *= radius / norm
        if np.all(evals > 0) and np.all(np.abs(step) <= 1e-6 * np.maximum(1.0, np.abs(x))):
            break
        for _ in range(40):
            cand = np.maximum(x + step, lower)
            f_new = float(f(cand[None])[0])
            if f_new >= fx:
                break
            step *= 0.5
        else:
            break
        x, fx = cand, f_new
    on_bound = x <= lower + 1e-12
    if np.any(on_bound):
        return x, True, "mode on a bound"
    polished, ok = newton_polish(f, x)
    if float(f(polished[None])[0]) >= fx:
        x = polished
    return x, ok, "converged" if ok else "Newton polish did not reach the tolerance"
