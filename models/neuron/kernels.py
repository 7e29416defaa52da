"""Fused numba loops of the FA-I unit (private; see :mod:`feeler.models.neuron`).

One pass over the samples does everything: increments, window sum, threshold. With
``c_j = Σ_i w_i |ε_{i,j} − ε_{i,j−1}|`` (the receptor output integrated over its hold
interval (t_{j−1}, t_j] at unit gain; ``c_0 = 0`` at a record's start) the boxcar
window sum is

    u1(t_k) = Σ_{j ≤ k} c_j · |(t_{j−1}, t_j] ∩ (t_k − τ, t_k]| / Δt_j,

full intervals count whole and the interval straddling t_k − τ by its fraction (X is
linear inside each interval). The full-interval sum slides (add the newest interval,
drop those that left) with error-free transformations (Knuth's TwoSum): the rounding
error of every add and subtract is carried in a compensation term, so residue of values
that left the window never accumulates — 10⁸-sample streams do not drift, and a quiet
window after loud ones keeps its relative precision.

Every compiled function and its callees live in one file: numba's cache is keyed on
the file of the cached function only. Uniformly sampled records (and streams of
uniform single-receptor chunks) take the faster loops of :mod:`feeler.models.neuron.uniform`;
this general loop serves any sampling and the exponential kernel.

Streaming: a :class:`Carry` holds what the next chunk needs — the last strain sample,
the samples still in (or straddling) the window as (t, c) history, the running sum and
its compensation.
"""
from __future__ import annotations

import math
from functools import partial

import numba as nb
import numpy as np

from feeler.models.neuron.threads import run_parallel, threads_for


__all__ = ["Carry", "boxcar", "exponential", "finite", "pick"]


class Carry:
    """State carried across chunks for ``rows`` channels (see module docstring)."""

    def __init__(self, rows: int):
        self.prev = np.zeros((rows, 0))   # last strain sample per receptor (rows, n_rec) once set
        self.t_hist = np.empty(0)          # history times, oldest first
        self.c_hist = np.empty((rows, 0))  # history increments
        self.sum = np.zeros(rows)          # Σ c over whole intervals [lo, end)
        self.comp = np.zeros(rows)         # TwoSum compensation of that sum
        self.lo = 1                        # first whole interval, index into history+chunk
        self.u = np.zeros(rows)            # exponential kernel: last u
        self.t_last = 0.0


@nb.njit(inline="always")
def _two_sum(s, x):
    t = s + x
    bp = t - s
    return t, (s - (t - bp)) + (x - bp)


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _increments(x, w, prev, have_prev, cv, H):
    """cv[H + k] = Σ_r w_r |x_{r,k} − x_{r,k−1}| for the chunk x (n_rec, n); the first
    sample differs from ``prev`` when a stream continues, else is 0 (ε̇_0 = 0)."""
    n = x.shape[1]
    if x.shape[0] == 1:
        w0 = w[0]
        for k in range(1, n):
            cv[H + k] = w0 * abs(x[0, k] - x[0, k - 1])
    else:
        for k in range(1, n):
            c = 0.0
            for r in range(x.shape[0]):
                c += w[r] * abs(x[r, k] - x[r, k - 1])
            cv[H + k] = c
    c = 0.0
    if have_prev:
        for r in range(x.shape[0]):
            c += w[r] * abs(x[r, 0] - prev[r])
    cv[H] = c


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _window(cv, tv, H, s, comp, lo, tau, a, h, clamp, out):
    """Boxcar over the virtual record (history then chunk) from index H on.

    Writes z (or u1 when not clamp) to ``out``; returns (s, comp, lo)."""
    for v in range(H, cv.shape[0]):
        s, e = _two_sum(s, cv[v])
        comp += e
        T = tv[v] - tau
        # drop whole intervals whose left edge t_{lo−1} lies before the window start
        while lo <= v and tv[lo - 1] < T:
            s, e = _two_sum(s, -cv[lo])
            comp += e
            lo += 1
        u = s + comp
        if lo >= 2 and tv[lo - 1] > T:  # the interval straddling T counts by its fraction
            u += cv[lo - 1] * ((tv[lo - 1] - T) / (tv[lo - 1] - tv[lo - 2]))
        if clamp:
            z = a * u - h
            out[v - H] = z if z > 0.0 else 0.0
        else:
            out[v - H] = u
    return s, comp, lo


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _boxcar_row(r, x, w, tv, prev, have_prev, cv, H, s, comp, lo, tau, a, h, clamp, out, lo_out):
    _increments(x[r], w, prev[r], have_prev, cv[r], H)
    s[r], comp[r], lo_out[r] = _window(cv[r], tv, H, s[r], comp[r], lo, tau, a, h, clamp, out[r])


# Rows in parallel on the cores that are free now (models/neuron/threads.py); one row,
# little work or a busy machine runs serially. The two loops are separate functions:
# numba's cache is keyed on the Python function, so one function compiled twice
# (parallel and serial) would load one build for both.
@nb.njit(cache=True, parallel=True)
def _boxcar_rows_par(*args):
    for r in nb.prange(args[0].shape[0]):
        _boxcar_row(r, *args)


@nb.njit(cache=True)
def _boxcar_rows_ser(*args):
    for r in range(args[0].shape[0]):
        _boxcar_row(r, *args)


def pick(par, ser, rows: int, n: int):
    """The loop to run for ``rows`` × ``n`` samples: ``ser``, or ``par`` on the threads
    :func:`~feeler.models.neuron.threads.threads_for` gives now."""
    k = threads_for(rows * n, rows)
    return ser if k == 1 else partial(run_parallel, par, k)


def boxcar(x: np.ndarray, w: np.ndarray, t: np.ndarray, tau: float, carry: Carry, *,
           a: float = 1.0, h: float = 0.0, clamp: bool = False) -> np.ndarray:
    """Boxcar z (``clamp``) or u₁ for strain ``x (rows, n_rec, n)``, weights ``w (n_rec,)``.

    Continues the stream held by ``carry`` (a fresh :class:`Carry` for a whole record)
    and updates it."""
    rows, n = x.shape[0], x.shape[2]
    out = np.empty((rows, n))
    if n == 0:
        return out
    cr = carry
    H = cr.t_hist.shape[0]
    tv = np.concatenate([cr.t_hist, t]) if H else t
    cv = np.empty((rows, H + n))
    if H:
        cv[:, :H] = cr.c_hist
    have_prev = cr.prev.shape[1] == x.shape[1]
    prev = cr.prev if have_prev else np.zeros((rows, x.shape[1]))
    lo_out = np.empty(rows, dtype=np.int64)
    run = pick(_boxcar_rows_par, _boxcar_rows_ser, rows, n)
    run(x, w, tv, prev, have_prev, cv, H, cr.sum, cr.comp, cr.lo,
        float(tau), float(a), float(h), clamp, out, lo_out)
    lo = int(lo_out[0])  # identical for every row (it depends on t only)
    keep = max(lo - 2, 0)  # history needed: intervals from lo − 1 on, and t_{lo−2}
    cr.t_hist = tv[keep:].copy()
    cr.c_hist = cv[:, keep:].copy()
    cr.lo = lo - keep
    cr.prev = x[:, :, -1].copy()
    return out


def finite(carry: Carry) -> bool:
    """False when a non-finite sample entered the record (NaN/inf persist in the sums)."""
    return bool(np.isfinite(carry.sum + carry.comp).all() and np.isfinite(carry.u).all())


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _exponential_row(c, t, have_prev, t_last, u, tau, a, h, clamp, out):
    """w(s) = e^(−s/τ): u_k = e^(−Δ/τ)·u_{k−1} + c_k·τ(1 − e^(−Δ/τ))/Δ, exact for the
    piecewise-constant receptor output. Returns the last u."""
    tp = t_last
    for k in range(t.shape[0]):
        if k == 0 and not have_prev:
            u = 0.0
        else:
            d = t[k] - tp
            gain = -math.expm1(-d / tau) * tau / d   # τ(1 − e^(−d/τ))/d, stable for d ≪ τ
            u = math.exp(-d / tau) * u + c[k] * gain
        tp = t[k]
        if clamp:
            z = a * u - h
            out[k] = z if z > 0.0 else 0.0
        else:
            out[k] = u
    return u


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _exponential_one(r, x, w, t, prev, have_prev, t_last, u, tau, a, h, clamp, out, c):
    _increments(x[r], w, prev[r], have_prev, c[r], 0)
    u[r] = _exponential_row(c[r], t, have_prev, t_last, u[r], tau, a, h, clamp, out[r])


@nb.njit(cache=True, parallel=True)
def _exponential_rows_par(*args):
    for r in nb.prange(args[0].shape[0]):
        _exponential_one(r, *args)


@nb.njit(cache=True)
def _exponential_rows_ser(*args):
    for r in range(args[0].shape[0]):
        _exponential_one(r, *args)


def exponential(x: np.ndarray, w: np.ndarray, t: np.ndarray, tau: float, carry: Carry, *,
                a: float = 1.0, h: float = 0.0, clamp: bool = False) -> np.ndarray:
    """Exponential-kernel z (``clamp``) or u₁; same layout as :func:`boxcar`."""
    rows, n = x.shape[0], x.shape[2]
    out = np.empty((rows, n))
    if n == 0:
        return out
    cr = carry
    have_prev = cr.prev.shape[1] == x.shape[1]
    prev = cr.prev if have_prev else np.zeros((rows, x.shape[1]))
    run = pick(_exponential_rows_par, _exponential_rows_ser, rows, n)
    run(x, w, t, prev, have_prev, cr.t_last, cr.u, float(tau), float(a),
                      float(h), clamp, out, np.empty((rows, n)))
    cr.prev = x[:, :, -1].copy()
    cr.t_last = float(t[-1])
    return out
