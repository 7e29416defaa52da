"""Boxcar loops for uniformly sampled records and streams (private; see kernels).

With Δt fixed, τ = (m + frac)·Δt fixes the window's shape:

    u1_k = Σ_{j=k−m+1..k} c_j + frac·c_{k−m}    (c_j = 0 for j ≤ 0),

so the slide adds c_k − c_{k−m} with no pointer walk and no division. The increments
are recomputed from the strain (no array of them is stored). Several receptors slide
one compensated (TwoSum) sum (:func:`_uniform_row`). A single receptor runs in four
interleaved lanes of plain adds (:func:`_lanes`): the sliding sum is a chain of
dependent additions, so one record runs at that chain's latency; four segments, each
started from an exact sum of the window before it, give four independent chains, and
the sum is re-derived exactly often enough to keep every output within 1e-10. A long
record is also cut across the threads (:func:`_split_row`). :class:`UniformStream`
runs streams of uniform chunks on the same loops. Results equal the general loop of
:mod:`~feeler.models.neuron.kernels` up to rounding.

Kept in one file with everything it calls, because numba's cache is keyed on the file
of the cached function only.
"""
from __future__ import annotations

import math

import numba as nb
import numpy as np

from feeler.models.neuron import kernels

__all__ = ["boxcar_uniform", "window_shape", "UniformStream"]


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
def _cj(x, k, m, ck):
    """c_{k−m}, the increment leaving the window (c_k itself when m = 0)."""
    if m == 0:
        return ck
    if k - m >= 1:
        return _c(x, k - m)
    return 0.0


@nb.njit(inline="always")
def _emit(out, k, u, a, h, clamp):
    if clamp:
        z = a * u - h
        out[k] = z if z > 0.0 else 0.0
    else:
        out[k] = u


@nb.njit(inline="always")
def _fast_step(x, k, m, frac, ratio, w0, a, h, clamp, out, s, big, flag):
    """One plain-add slide of a lane to sample k: emits u, tracks the largest window
    sum ``big`` and flags a fall below ``big/ratio`` (see :func:`_lanes`)."""
    c = _c(x, k)
    cj = _cj(x, k, m, c)
    s += c - cj
    big = max(big, s)
    _emit(out, k, w0 * (s + frac * cj), a, h, clamp)
    return s, big, flag | (s * ratio < big)


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _window_before(x, start, m):
    """Compensated sum of c_{start−m} … c_{start−1}: the exact state before ``start``."""
    s = 0.0
    comp = 0.0
    if m > 0:
        for j in range(max(start - m, 1), start):
            s, e = _two_sum(s, _c(x, j))
            comp += e
    return s + comp


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _exact_span(x, start, stop, w0, m, frac, a, h, clamp, out):
    """Outputs start … stop − 1 with a compensated (TwoSum) slide, from an exact start."""
    s = _window_before(x, start, m)
    comp = 0.0
    for k in range(start, stop):
        ck = _c(x, k)
        cj = _cj(x, k, m, ck)
        d, e1 = _two_sum(ck, -cj)
        s, e2 = _two_sum(s, d)
        comp += e1 + e2
        _emit(out, k, w0 * ((s + comp) + frac * cj), a, h, clamp)
    return s + comp


@nb.njit(inline="always")
def _block_end(x, base, lo, hi, flagged, resync, s, big, w0, m, frac, a, h, clamp, out):
    """After a lane's block: recompute a flagged block with the compensated slide, or
    re-derive the sum exactly when the period is up. Returns (s, big)."""
    if flagged:
        s = _exact_span(x, base + lo, base + hi, w0, m, frac, a, h, clamp, out)
        return s, s
    if resync:
        s = _window_before(x, base + hi, m)
        return s, s
    return s, big


# block length of the fast slide; the sum is re-derived exactly at block ends
_BLOCK = 4096
# relative error allowed to the fast slide's rounding (the drift bound is 1e-9)
_TOL = 1e-10
_EPS = 2.0 ** -52


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _lanes(x, w0, m, frac, a, h, clamp, out, start, stop):
    """u₁ or z of ``w0·x`` (one receptor, ``x (n,)``) with τ = (m + frac)·Δt.

    Four lanes slide with plain adds. Rounding of a plain slide is at most
    ``ops·ε·big`` (big the largest window sum since the sum was last derived exactly),
    so the sum is re-derived exactly every ``period`` samples, and a block in which the
    window sum fell below ``big/ratio`` (a quiet window after loud ones) is recomputed
    with the compensated slide: every output keeps a relative error ≤ ``_TOL``.
    Outputs ``start`` … ``stop`` − 1 are written (earlier ones are the caller's: a
    stream's first samples, whose window reaches into the previous chunk, or another
    thread's part of the record).
    Returns the sum of the lanes' final window sums, NaN if a NaN/inf entered anywhere."""
    n = stop
    seg = (n - start) // 4
    period = max(16 * _BLOCK, ((4 * m) // _BLOCK + 1) * _BLOCK)
    ratio = max(2.0, _TOL / (period * _EPS))
    b0 = start
    b1, b2, b3 = b0 + seg, b0 + 2 * seg, b0 + 3 * seg
    s0, s1 = _window_before(x, b0, m), _window_before(x, b1, m)
    s2, s3 = _window_before(x, b2, m), _window_before(x, b3, m)
    g0, g1, g2, g3 = s0, s1, s2, s3
    done = 0
    poisoned = False
    for lo in range(0, seg, _BLOCK):
        hi = min(lo + _BLOCK, seg)
        f0 = f1 = f2 = f3 = False
        for j in range(lo, hi):
            s0, g0, f0 = _fast_step(x, b0 + j, m, frac, ratio, w0, a, h, clamp, out, s0, g0, f0)
            s1, g1, f1 = _fast_step(x, b1 + j, m, frac, ratio, w0, a, h, clamp, out, s1, g1, f1)
            s2, g2, f2 = _fast_step(x, b2 + j, m, frac, ratio, w0, a, h, clamp, out, s2, g2, f2)
            s3, g3, f3 = _fast_step(x, b3 + j, m, frac, ratio, w0, a, h, clamp, out, s3, g3, f3)
        done += hi - lo
        # NaN/inf persist inside a block; remember them before a resync re-derives the sums
        poisoned |= not (math.isfinite(s0) and math.isfinite(s1) and math.isfinite(s2) and math.isfinite(s3))
        resync = done >= period
        s0, g0 = _block_end(x, b0, lo, hi, f0, resync, s0, g0, w0, m, frac, a, h, clamp, out)
        s1, g1 = _block_end(x, b1, lo, hi, f1, resync, s1, g1, w0, m, frac, a, h, clamp, out)
        s2, g2 = _block_end(x, b2, lo, hi, f2, resync, s2, g2, w0, m, frac, a, h, clamp, out)
        s3, g3 = _block_end(x, b3, lo, hi, f3, resync, s3, g3, w0, m, frac, a, h, clamp, out)
        if resync:
            done = 0
    s3 = _exact_span(x, b0 + 4 * seg, n, w0, m, frac, a, h, clamp, out) if n > b0 + 4 * seg else s3
    total = w0 * (s0 + s1 + s2 + s3)
    return np.nan if poisoned else total


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _uniform_row(x, w, m, frac, a, h, clamp, out, start):
    """Any number of receptors ``x (n_rec, n)`` in one lane: the slide adds the exact
    difference c_k − c_{k−m} (TwoSum) to a compensated sum. Outputs from ``start`` on
    (the state before it is summed exactly first). Returns the final sum."""
    n = x.shape[1]
    nr = x.shape[0]
    s = 0.0
    comp = 0.0
    for j in range(max(start - m, 1), start):
        for r in range(nr):
            s, e = _two_sum(s, w[r] * abs(x[r, j] - x[r, j - 1]))
            comp += e
    if start == 0 and n:
        out[0] = 0.0
    for k in range(max(start, 1), n):
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


def _uniform_rows_py(x, w, m, frac, a, h, clamp, out, final, start):
    n = x.shape[2]
    lanes = x.shape[1] == 1 and n - start >= 64 and m < (n - start) // 8
    for r in nb.prange(x.shape[0]):
        if lanes:
            final[r] = _lanes(x[r, 0], w[0], m, frac, a, h, clamp, out[r], start, n)
        else:
            final[r] = _uniform_row(x[r], w, m, frac, a, h, clamp, out[r], start)


@nb.njit(cache=True, parallel=True)
def _split_row(x, w0, m, frac, a, h, clamp, out, start, parts):
    """One long single-receptor record cut into ``parts`` pieces, one per thread (each
    piece's lanes start from the exact window before it). Returns the summed finals."""
    n = x.shape[0]
    finals = np.zeros(parts)
    size = (n - start) // parts
    for p in nb.prange(parts):
        lo = start + p * size
        hi = n if p == parts - 1 else lo + size
        finals[p] = _lanes(x, w0, m, frac, a, h, clamp, out, lo, hi)
    return finals.sum()


# a single record this long is cut across the cores (shorter ones: start-up costs more)
_SPLIT_MIN_SAMPLES = 1 << 18


_uniform_rows_par = nb.njit(cache=True, parallel=True)(_uniform_rows_py)
_uniform_rows_ser = nb.njit(cache=True)(_uniform_rows_py)


def window_shape(dt: float, tau: float, n: int) -> tuple[int, float]:
    """(m, frac) with τ = (m + frac)·Δt; beyond a record of n samples the window is the
    whole record (m = n + 1, frac = 0)."""
    ratio = tau / dt
    m = int(min(math.floor(ratio), n + 1))
    return m, (ratio - math.floor(ratio) if m <= n else 0.0)


def boxcar_uniform(x: np.ndarray, w: np.ndarray, dt: float, tau: float, final: np.ndarray, *,
                   a: float = 1.0, h: float = 0.0, clamp: bool = False, start: int = 0,
                   out: np.ndarray | None = None) -> np.ndarray:
    """Boxcar z or u₁ of ``x (rows, n_rec, n)`` sampled every ``dt``: a whole record
    (``x[..., 0]`` is its first sample), outputs from ``start`` on (earlier entries of the
    returned array are left unset).

    ``final (rows,)`` receives the final window sums (NaN when a NaN/inf entered);
    ``out (rows, n)``, when given, receives the outputs (else a new array)."""
    rows, n = x.shape[0], x.shape[2]
    mm, frac = window_shape(dt, tau, n)
    if out is None:
        out = np.empty((rows, n))
    threads = nb.get_num_threads()
    if rows == 1 and x.shape[1] == 1 and threads > 1 and n - start >= _SPLIT_MIN_SAMPLES \
            and mm < (n - start) // (8 * threads):
        final[0] = _split_row(x[0, 0], float(w[0]), mm, frac, float(a), float(h), clamp, out[0], start, threads)
        return out
    run = kernels.pick(_uniform_rows_par, _uniform_rows_ser, rows, n)
    run(x, w, mm, frac, float(a), float(h), clamp, out, final, start)
    return out


class UniformStream:
    """The boxcar stream of uniformly sampled single-receptor chunks, on the fast loops.

    Keeps the last m + 2 samples (strain and time) as history: the first m + 1 outputs of
    a chunk are computed on history + chunk head, the rest on the chunk alone from
    ``start = m + 1``. :meth:`general_carry` hands over to the general loop (for a chunk
    that breaks the uniform sampling) by replaying the history."""

    def __init__(self, rows: int, dt: float, tau: float):
        self.dt, self.tau = dt, tau
        self.m = int(math.floor(tau / dt))
        self.hist_x = np.empty((rows, 1, 0))
        self.hist_t = np.empty(0)

    def accepts(self, dt: float) -> bool:
        return abs(dt - self.dt) <= 1e-9 * self.dt

    def push(self, x: np.ndarray, w: np.ndarray, t: np.ndarray, final: np.ndarray, *, a: float,
             h: float, clamp: bool) -> np.ndarray:
        rows, n = x.shape[0], x.shape[2]
        head = min(n, self.m + 1)
        H = self.hist_t.shape[0]
        out = np.empty((rows, n))
        f_head = np.zeros(rows)
        xx = np.ascontiguousarray(np.concatenate([self.hist_x, x[:, :, :head]], axis=2))
        out[:, :head] = boxcar_uniform(xx, w, self.dt, self.tau, f_head, a=a, h=h, clamp=clamp,
                                       start=H)[:, H:]
        final[:] = f_head
        if n > head:
            f_rest = np.zeros(rows)
            boxcar_uniform(x, w, self.dt, self.tau, f_rest, a=a, h=h, clamp=clamp, start=head, out=out)
            final += f_rest
        keep = self.m + 2
        if n >= keep:
            self.hist_x, self.hist_t = x[:, :, n - keep:].copy(), t[n - keep:].copy()
        else:
            self.hist_x = np.concatenate([self.hist_x, x], axis=2)[:, :, -keep:]
            self.hist_t = np.concatenate([self.hist_t, t])[-keep:]
        return out

    def general_carry(self, w: np.ndarray) -> "kernels.Carry":
        """The general loop's carry after the samples seen so far (history replayed)."""
        carry = kernels.Carry(self.hist_x.shape[0])
        if self.hist_t.shape[0]:
            kernels.boxcar(np.ascontiguousarray(self.hist_x), w, self.hist_t, self.tau, carry)
        return carry
