"""Boxcar loops for uniformly sampled records and streams (private; see kernels).

With Δt fixed, τ = (m + frac)·Δt fixes the window's shape:

    u1_k = Σ_{j=k−m+1..k} c_j + frac·c_{k−m}    (c_j = 0 for j ≤ 0),

so the slide adds c_k − c_{k−m} with no pointer walk and no division. The increments
are recomputed from the strain, a block of 1024 samples at a time. Several receptors
slide one compensated (TwoSum) sum (:func:`_uniform_row`). A single receptor runs the
strided slide (:func:`_strided`): one sliding sum is a chain of dependent additions,
but s_k − s_{k−8} is the sum of eight consecutive c_j − c_{j−m}, so the residues of k
mod 8 are eight independent lanes of plain adds that fill one vector register. The
lanes' sums are re-derived exactly often enough, and a block where a sum fell far
below its lane's largest is recomputed compensated, to keep every output within 1e-10
(windows under eight samples are summed directly, :func:`_direct`). A long record is
also cut across the threads (:func:`split_row`), each checking its piece's times first.
:class:`UniformStream` runs streams of uniform chunks on the same loops. Results equal
the general loop of :mod:`~feeler.models.neuron.kernels` up to rounding.

Kept in one file with everything it calls, because numba's cache is keyed on the file
of the cached function only.
"""
from __future__ import annotations

import math

import numba as nb
import numpy as np

from feeler.models.neuron import kernels
from feeler.models.neuron.threads import run_parallel, threads_for

__all__ = ["boxcar_uniform", "steps_off_grid", "split_parts", "split_row", "window_shape", "UniformStream"]


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


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _window_before(x, start, m):
    """Compensated sum of c_{start−m} … c_{start−1}, the exact state before ``start``,
    as (sum, compensation): collapsing them into one float would leave an offset of
    ε·sum in every later window, large against a quiet window after loud ones."""
    s = 0.0
    comp = 0.0
    if m > 0:
        for j in range(max(start - m, 1), start):
            s, e = _two_sum(s, _c(x, j))
            comp += e
    return s, comp


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _exact_span(x, start, stop, w0, m, frac, a, h, clamp, out):
    """Outputs start … stop − 1 with a compensated (TwoSum) slide, from an exact start."""
    s, comp = _window_before(x, start, m)
    for k in range(start, stop):
        ck = _c(x, k)
        cj = _cj(x, k, m, ck)
        d, e1 = _two_sum(ck, -cj)
        s, e2 = _two_sum(s, d)
        comp += e1 + e2
        _emit(out, k, w0 * ((s + comp) + frac * cj), a, h, clamp)
    return s + comp


# samples per block of the vector loops (their buffers stay in the L1 cache)
_BLOCK = 1024
# lanes of the strided slide: residues of the sample index modulo _L
_L = 8
# relative error allowed to the plain-add slide's rounding (the drift bound is 1e-9)
_TOL = 1e-10
_EPS = 2.0 ** -52


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _exact_state(x, k, m, s, g):
    """s[q] = g[q] = the window sum s_{k−8+q} for q = 0 … 7, compensated (exact to
    rounding): the strided slide's state before sample k."""
    acc, comp = _window_before(x, k - _L + 1, m)
    s[0] = acc + comp
    for q in range(1, _L):
        j = k - _L + q
        ck = _c(x, j) if j >= 1 else 0.0
        cj = _c(x, j - m) if j - m >= 1 else 0.0
        d, e1 = _two_sum(ck, -cj)
        acc, e2 = _two_sum(acc, d)
        comp += e1 + e2
        s[q] = acc + comp
    for q in range(_L):
        g[q] = s[q]


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _leaving(x, k0, nn, m, cm):
    """cm[i] = c_{k0+i−m} for i = 0 … nn − 1 (c_j = 0 for j ≤ 0); reads x only up to
    k0 + nn − 1 − m. Vectorised away from the record's start."""
    lo = min(max(m + 1 - k0, 0), nn)     # the first i with k0 + i − m ≥ 1
    for i in range(lo):
        cm[i] = 0.0
    if lo < nn:
        xc, xd, cv = x[k0 - m + lo:], x[k0 - m + lo - 1:], cm[lo:]
        for i in range(nn - lo):
            cv[i] = abs(xc[i] - xd[i])


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _pairs(x, k0, nn, m, p, cm):
    """cm[i] = c_{k0+i−m} for i = 0 … nn − 1, and the pair sums
    p[i] = d_{k0+i} + d_{k0+i+1} (d_j = c_j − c_{j−m}) for i = 0 … nn − 2 (c_j = 0 for
    j ≤ 0): the first level of the strided slide's tree, so that its loop loads four
    pair sums per sample instead of eight increments. Reads x up to k0 + nn − 1;
    vectorised away from the record's start."""
    if k0 - m - 1 >= 0:
        xa, xb, xn = x[k0:], x[k0 - 1:], x[k0 + 1:]
        xc, xd, xe = x[k0 - m:], x[k0 - m - 1:], x[k0 - m + 1:]
        for i in range(nn - 1):
            cj = abs(xc[i] - xd[i])
            cm[i] = cj
            p[i] = (abs(xa[i] - xb[i]) - cj) + (abs(xn[i] - xa[i]) - abs(xe[i] - xc[i]))
        cm[nn - 1] = abs(xc[nn - 1] - xd[nn - 1])
    else:
        for i in range(nn):
            k = k0 + i
            ck = _c(x, k) if k >= 1 else 0.0
            cj = _c(x, k - m) if k - m >= 1 else 0.0
            cm[i] = cj
            if i == nn - 1:
                break
            ck1 = _c(x, k + 1) if k + 1 >= 1 else 0.0
            cj1 = _c(x, k + 1 - m) if k + 1 - m >= 1 else 0.0
            p[i] = (ck - cj) + (ck1 - cj1)


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _strided_block(x, k0, nn, m, frac, w0, a, h, clamp, o, s, g, p, cm, ratio):
    """Outputs k0 … k0 + nn − 1 by the strided slide, into o[0 : nn]; returns whether
    any fell below ``g/ratio`` (then the block is recomputed, see :func:`_strided`).

    With s_k the window sum of whole intervals, s_k − s_{k−8} = Σ_{j=k−7..k} d_j
    (d_j = c_j − c_{j−m}), so each residue of k mod 8 is a lane of plain adds, and the
    eight lanes are one vector. ``s[0:8]``/``g[0:8]`` carry the lanes' sums and running
    maxima in and out."""
    _pairs(x, k0 - _L + 1, nn + _L - 1, m, p, cm)
    low = False
    for i in range(nn):
        # s_{k} = s_{k−8} + (eight-sample sum of d, a pairwise tree whose first level is
        # the pair sums p); the dependence distance is 8: one vector register carries
        # the eight lanes
        s[i + _L] = s[i] + ((p[i] + p[i + 2]) + (p[i + 4] + p[i + 6]))
        v = s[i + _L]
        gi = v if v > g[i] else g[i]
        g[i + _L] = gi
        low |= v * ratio < gi
        u = w0 * (v + frac * cm[i + _L - 1])
        if clamp:
            z = a * u - h
            o[i] = z if z > 0.0 else 0.0
        else:
            o[i] = u
    for q in range(_L):
        s[q] = s[nn + q]
        g[q] = g[nn + q]
    return low


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _strided(x, w0, m, frac, a, h, clamp, out, start, stop):
    """u₁ or z of ``w0·x`` (one receptor, ``x (n,)``), τ = (m + frac)·Δt with m ≥ 8,
    outputs ``start`` … ``stop`` − 1 (earlier ones are the caller's: a stream's first
    samples, whose window reaches into the previous chunk, or another thread's part).

    Eight lanes of plain adds in one vector (:func:`_strided_block`). A lane's terms
    are bounded by its window sums (m ≥ 8), so each step rounds by at most ``9ε·g``, g
    the lane's largest sum since it was last derived exactly. The state is re-derived
    exactly every ``period`` samples, and a block where some sum fell below
    ``g/ratio`` (a quiet window after loud ones) is recomputed with the compensated
    slide: every output keeps a relative error ≤ ``_TOL``.
    Returns the last window sum, NaN if a NaN/inf entered anywhere."""
    s = np.empty(_BLOCK + _L)
    g = np.empty(_BLOCK + _L)
    pp = np.empty(_BLOCK + _L)
    cm = np.empty(_BLOCK + _L)
    period = max(64 * _BLOCK, ((4 * m) // _BLOCK + 1) * _BLOCK)
    ratio = max(2.0, _TOL / (9.0 * (period // _L + _BLOCK) * _EPS))
    _exact_state(x, start, m, s, g)
    done = 0
    poisoned = False
    for k0 in range(start, stop, _BLOCK):
        nn = min(_BLOCK, stop - k0)
        low = _strided_block(x, k0, nn, m, frac, w0, a, h, clamp, out[k0:], s, g, pp, cm, ratio)
        # NaN/inf persist in the lanes until the state is re-derived: look before that
        for q in range(_L):
            poisoned |= not math.isfinite(s[q])
        done += nn
        if low:
            poisoned |= not math.isfinite(_exact_span(x, k0, k0 + nn, w0, m, frac, a, h, clamp, out))
        if low or done >= period:
            _exact_state(x, k0 + nn, m, s, g)
            done = 0
    return np.nan if poisoned else w0 * s[_L - 1]


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _direct(x, w0, m, frac, a, h, clamp, out, start, stop):
    """Like :func:`_strided` for windows shorter than eight samples (m < 8): each
    output sums its m + 1 increments directly (vectorised over the block), so nothing
    is carried and nothing drifts."""
    cb = np.empty(_BLOCK + _L)
    acc = np.empty(_BLOCK)
    bad = 0
    last = 0.0
    for k0 in range(start, stop, _BLOCK):
        nn = min(_BLOCK, stop - k0)
        _leaving(x, k0, nn + m, m, cb)          # cb[i] = c_{k0+i−m}
        for i in range(nn):
            acc[i] = 0.0
        for q in range(m):                     # c_{k0+i−q} = cb[i + m − q]
            for i in range(nn):
                acc[i] += cb[i + m - q]
        o = out[k0:]
        for i in range(nn):
            v = acc[i] + frac * cb[i]
            bad += not (abs(v) < math.inf)
            u = w0 * v
            if clamp:
                z = a * u - h
                o[i] = z if z > 0.0 else 0.0
            else:
                o[i] = u
        last = acc[nn - 1]
    return np.nan if bad else w0 * last


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _single(x, w0, m, frac, a, h, clamp, out, start, stop):
    """One receptor, outputs ``start`` … ``stop`` − 1 (see :func:`_strided`)."""
    if stop <= start:
        return 0.0
    if m < _L:
        return _direct(x, w0, m, frac, a, h, clamp, out, start, stop)
    return _strided(x, w0, m, frac, a, h, clamp, out, start, stop)


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


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _any_row(r, x, w, m, frac, a, h, clamp, out, final, start):
    if x.shape[1] == 1:
        final[r] = _single(x[r, 0], w[0], m, frac, a, h, clamp, out[r], start, x.shape[2])
    else:
        final[r] = _uniform_row(x[r], w, m, frac, a, h, clamp, out[r], start)


# separate functions, not one compiled twice: see kernels._boxcar_rows_par
@nb.njit(cache=True, parallel=True)
def _uniform_rows_par(*args):
    for r in nb.prange(args[0].shape[0]):
        _any_row(r, *args)


@nb.njit(cache=True)
def _uniform_rows_ser(*args):
    for r in range(args[0].shape[0]):
        _any_row(r, *args)


@nb.njit(cache=True, nogil=True)
def steps_off_grid(t, dt, tol):
    """Steps of t farther than ``tol`` from ``dt`` (NaN counts), in one branch-free
    (vectorised) pass. With 0 ≤ tol < dt, none off the grid also means t is finite and
    strictly increasing."""
    far = 0
    ta, tb = t[1:], t[:-1]
    for i in range(t.shape[0] - 1):
        far += not (abs(ta[i] - tb[i] - dt) <= tol)
    return far


@nb.njit(cache=True, parallel=True)
def split_row(x, t, dt, tol, w0, m, frac, a, h, clamp, out, start, parts):
    """One long single-receptor record cut into ``parts`` pieces, one per thread (each
    piece starts from the exact window sums before it).

    When ``t`` is given (a whole record), each thread first checks its piece of t
    against the grid (Δt = ``dt`` ± ``tol``, tol < dt) and computes its outputs only if
    the piece is on it: t is read once, in parallel, next to the strain.
    Returns (summed finals, steps off the grid)."""
    n = x.shape[0]
    finals = np.zeros(parts)
    far = np.zeros(parts, dtype=np.int64)
    size = (n - start) // parts
    for p in nb.prange(parts):
        lo = start + p * size
        hi = n if p == parts - 1 else lo + size
        if t.shape[0]:
            far[p] = steps_off_grid(t[max(lo - 1, 0):hi], dt, tol)
        if far[p] == 0:
            finals[p] = _single(x, w0, m, frac, a, h, clamp, out, lo, hi)
    return finals.sum(), far.sum()


# a single record this long is cut across the cores (shorter ones: start-up costs more)
_SPLIT_MIN_SAMPLES = 1 << 16


def window_shape(dt: float, tau: float, n: int) -> tuple[int, float]:
    """(m, frac) with τ = (m + frac)·Δt; beyond a record of n samples the window is the
    whole record (m = n + 1, frac = 0)."""
    ratio = tau / dt
    m = int(min(math.floor(ratio), n + 1))
    return m, (ratio - math.floor(ratio) if m <= n else 0.0)


def split_parts(x: np.ndarray, n_out: int, mm: int) -> int:
    """Threads to cut a single-receptor record across, by its length and the cores free
    now (0: do not cut). Run :func:`split_row` on that many threads (``run_parallel``)."""
    if x.shape[0] != 1 or x.shape[1] != 1 or n_out < _SPLIT_MIN_SAMPLES:
        return 0
    threads = threads_for(n_out)
    return threads if threads > 1 and mm < n_out // (8 * threads) else 0


# split_row's t when the times are already checked
_NO_T = np.empty(0)


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
    parts = split_parts(x, n - start, mm)
    if parts:
        final[0], _ = run_parallel(split_row, parts, x[0, 0], _NO_T, 0.0, 0.0, float(w[0]), mm, frac,
                                   float(a), float(h), clamp, out[0], start, parts)
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
        final[:] = 0.0
        if n > head:
            # first, so that the threads of the row loop take the new pages' first touch
            boxcar_uniform(x, w, self.dt, self.tau, final, a=a, h=h, clamp=clamp, start=head, out=out)
        f_head = np.zeros(rows)
        xx = np.ascontiguousarray(np.concatenate([self.hist_x, x[:, :, :head]], axis=2))
        out[:, :head] = boxcar_uniform(xx, w, self.dt, self.tau, f_head, a=a, h=h, clamp=clamp,
                                       start=H)[:, H:]
        final += f_head
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
