"""Frictionless contact condensed exactly onto the candidate nodes: an active-set solver.

Given the condensed compliance C (SPD, n_c × n_c) and the required displacement
``need`` (u must reach ``need`` where the plate touches), find contact forces p with

    g = C p − need ≥ 0,   p ≥ 0,   p·g = 0        (a linear complementarity problem)

by the primal–dual active-set method (warm-started from the previous step's set; a few
iterations per time step), falling back to Lawson–Hanson NNLS — itself an active-set
method — on the equivalent problem min ‖Lᵀp − L⁻¹need‖, C = L Lᵀ, if it cycles.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg as la
from scipy.optimize import nnls

from feeler.errors import SolverError

__all__ = ["solve_contact", "single_thread_blas"]

MAX_ITER = 60


def solve_contact(compliance: np.ndarray, need: np.ndarray, active: np.ndarray | None = None,
                  *, tol_mm: float = 1e-10):
    """Solve the condensed frictionless contact problem.

    Args:
        compliance (ndarray[n, n]): C, mm per (N/mm), symmetric positive definite.
        need (ndarray[n]): displacement (mm) each node must reach if it touches.
        active (ndarray[n] bool | None): initial guess of the contact set.
        tol_mm (float): tolerance on penetration, scaled by max |need|.
    Returns:
        (p ndarray[n] N/mm, active ndarray[n] bool)
    Raises:
        SolverError: the complementarity conditions are violated beyond tolerance.
    """
    n = len(need)
    scale = max(float(np.max(np.abs(need))), 1e-30)
    tol = tol_mm * max(scale, 1.0)
    act = (need > 0) if active is None else active.copy()
    stiff = 1.0 / np.diag(compliance)
    for _ in range(MAX_ITER):
        p = np.zeros(n)
        if act.any():
            idx = np.flatnonzero(act)
            p[idx] = la.cho_solve(la.cho_factor(compliance[np.ix_(idx, idx)]), need[idx])
        gap = compliance @ p - need
        new = (p - stiff * gap) > tol * stiff
        if np.array_equal(new, act):
            break
        act = new
    else:
        p = _nnls_contact(compliance, need)
        gap = compliance @ p - need
        act = p > 0
    violation = max(float(-gap.min()), float(np.max(np.abs(gap[act]), initial=0.0)),
                    float(-p.min()) * float(np.max(np.diag(compliance))))
    if violation > 1e-6 * max(scale, 1e-3):
        raise SolverError("frictionless contact (active set)", violation, "mm")
    return np.maximum(p, 0.0), act


def single_thread_blas():
    """Context limiting BLAS to one thread: the dense systems here are a few hundred wide,
    where threaded BLAS is 10-30× slower on a shared machine (measured)."""
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - threadpoolctl ships with the scientific stack
        import contextlib
        return contextlib.nullcontext()
    return threadpool_limits(limits=1, user_api="blas")


def _nnls_contact(compliance: np.ndarray, need: np.ndarray) -> np.ndarray:
    low = la.cholesky(compliance, lower=True)
    target = la.solve_triangular(low, need, lower=True)
    p, _ = nnls(low.T, target, maxiter=50 * len(need))
    return p
