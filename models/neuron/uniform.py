"""Boxcar loops for uniformly sampled whole records (private; see kernels).

With Δt fixed, τ = (m + frac)·Δt fixes the window's shape:

    u1_k = Σ_{j=k−m+1..k} c_j + frac·c_{k−m}    (c_j = 0 for j ≤ 0),

so the slide adds the exact difference c_k − c_{k−m} (TwoSum) to the compensated sum
with no pointer walk and no division. The increments are recomputed from the strain (no
array of them is stored). A single receptor runs in four interleaved lanes: the sliding
sum is a chain of dependent additions, so one record runs at that chain's latency;
four segments, each started from an exact compensated sum of the window before it,
give four independent chains that the processor overlaps. Results equal the one-lane
loop up to rounding.

Kept in one file with everything it calls, because numba's cache is keyed on the file
of the cached function only.
"""
from __future__ import annotations

import math

import numba as nb
import numpy as np

from feeler.models.neuron import kernels

__all__ = ["boxcar_uniform"]


@nb.njit(inline="always")
def _two_sum(s, x):
    """s + x as (sum, rounding error), exactly (Knuth); also in kernels.py, see above."""
    t = s + x
    bp = t - s
    return t, (s - (t - bp)) + (x - bp)


@nb.njit(inline="always")
def _c(x, k):
    return abs(x[k] - x[k - 1]) if k >= 1 else 0.0


@nb.njit(inline="always")
def _step(x, k, m, frac, s, comp):
    """Slide to sample k: add c_k, drop c_{k−m}; u = s + frac·c_{k−m} (see kernels)."""
    ck = _c(x, k)
    if m == 0:
        cj = ck
    elif k - m >= 1:
        cj = _c(x, k - m)
    else:
        cj = 0.0
    d, e1 = _two_sum(ck, -cj)
    s, e2 = _two_sum(s, d)
    comp += e1 + e2
    return s, comp, (s + comp) + frac * cj


@nb.njit(inline="always")
def _emit(out, k, u, a, h, clamp):
    if clamp:
        z = a * u - h
        out[k] = z if z > 0.0 else 0.0
    else:
        out[k] = u


@nb.njit(inline="always")
def _warm(x, start, m):
    """Compensated sum of c_{start−m} … c_{start−1}: the state before sample ``start``."""
    s = 0.0
    comp = 0.0
    if m > 0:
        for j in range(max(start - m, 1), start):
            s, e = _two_sum(s, _c(x, j))
            comp += e
    return s, comp


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _lanes(x, w0, m, frac, a, h, clamp, out):
    """u₁ or z of ``w0·x`` (one receptor, ``x (n,)``) with τ = (m + frac)·Δt.

    Returns the final compensated sum of the last lane (non-finite if a NaN/inf entered
    that lane; the caller checks every lane's output through it and the others)."""
    n = x.shape[0]
    seg = n // 4
    b1, b2, b3 = seg, 2 * seg, 3 * seg
    s0, c0 = 0.0, 0.0
    s1, c1 = _warm(x, b1, m)
    s2, c2 = _warm(x, b2, m)
    s3, c3 = _warm(x, b3, m)
    bad = 0.0
    for j in range(seg):
        s0, c0, u0 = _step(x, j, m, frac, s0, c0)
        s1, c1, u1 = _step(x, b1 + j, m, frac, s1, c1)
        s2, c2, u2 = _step(x, b2 + j, m, frac, s2, c2)
        s3, c3, u3 = _step(x, b3 + j, m, frac, s3, c3)
        _emit(out, j, w0 * u0, a, h, clamp)
        _emit(out, b1 + j, w0 * u1, a, h, clamp)
        _emit(out, b2 + j, w0 * u2, a, h, clamp)
        _emit(out, b3 + j, w0 * u3, a, h, clamp)
    for k in range(4 * seg, n):
        s3, c3, u3 = _step(x, k, m, frac, s3, c3)
        _emit(out, k, w0 * u3, a, h, clamp)
    bad = (s0 + c0) + (s1 + c1) + (s2 + c2) + (s3 + c3)  # NaN/inf persist in each lane
    return w0 * bad


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _uniform_row(x, w, m, frac, a, h, clamp, out):
    """A whole record sampled every Δt with τ = (m + frac)·Δt, m ≥ 0, 0 ≤ frac < 1:

        u1_k = Σ_{j=k−m+1..k} c_j + frac·c_{k−m}    (c_j = 0 for j ≤ 0)

    Same quantity as :func:`_window` without the pointer walk or the division; the
    increments are recomputed from the strain (no array of them is stored) and the
    slide adds the exact difference c_k − c_{k−m} (TwoSum) to the compensated sum."""
    n = x.shape[1]
    nr = x.shape[0]
    s = 0.0
    comp = 0.0
    if n:
        out[0] = 0.0
    for k in range(1, n):
        ck = 0.0
        for r in range(nr):
            ck += w[r] * abs(x[r, k] - x[r, k - 1])
        j = k - m            # the interval straddling t_k − τ (fraction ``frac``)
        if m == 0:
            cj = ck
        elif j >= 1:
            cj = 0.0
            for r in range(nr):
                cj += w[r] * abs(x[r, j] - x[r, j - 1])
        else:
            cj = 0.0
        d, e1 = _two_sum(ck, -cj)
        s, e2 = _two_sum(s, d)
        comp += e1 + e2
        u = (s + comp) + frac * cj
        if clamp:
            z = a * u - h
            out[k] = z if z > 0.0 else 0.0
        else:
            out[k] = u
    return s + comp


def _uniform_rows_py(x, w, m, frac, a, h, clamp, out, final):
    n = x.shape[2]
    lanes = x.shape[1] == 1 and n >= 64 and m < n // 8
    for r in nb.prange(x.shape[0]):
        if lanes:
            final[r] = _lanes(x[r, 0], w[0], m, frac, a, h, clamp, out[r])
        else:
            final[r] = _uniform_row(x[r], w, m, frac, a, h, clamp, out[r])


_uniform_rows_par = nb.njit(cache=True, parallel=True)(_uniform_rows_py)
_uniform_rows_ser = nb.njit(cache=True)(_uniform_rows_py)


def boxcar_uniform(x: np.ndarray, w: np.ndarray, dt: float, tau: float, carry, *,
                   a: float = 1.0, h: float = 0.0, clamp: bool = False) -> np.ndarray:
    """Boxcar z or u₁ of a whole record ``x (rows, n_rec, n)`` sampled every ``dt``.

    ``carry.sum`` receives the final running sums (non-finite when a NaN/inf entered);
    the carry cannot continue a stream after this call."""
    rows, n = x.shape[0], x.shape[2]
    ratio = tau / dt
    m = int(min(math.floor(ratio), n + 1))  # beyond the record the window is the whole record
    frac = ratio - math.floor(ratio) if m <= n else 0.0
    out = np.empty((rows, n))
    run = kernels.pick(_uniform_rows_par, _uniform_rows_ser, rows, n)
    run(x, w, m, frac, float(a), float(h), clamp, out, carry.sum)
    return out
