"""Argument checks of the neuron core: one-line ``ArgumentError`` naming the argument."""
from __future__ import annotations

import math

import numba as nb
import numpy as np

from feeler.errors import ArgumentError
from feeler.models.neuron.uniform import steps_off_grid

__all__ = ["check_params", "check_kernel", "check_signal", "check_weights", "check_times_uniform",
           "uniform_grid"]

KERNELS = ("boxcar", "exponential")


def _finite_scalar(name: str, value: object) -> float:
    try:
        v = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ArgumentError(name, value, "must be a real number") from None
    if not math.isfinite(v):
        raise ArgumentError(name, value, "must be finite")
    return v


def check_params(*, a: object = None, tau: object = None, h: object = None) -> tuple:
    """Validate the domain a > 0, τ > 0 (seconds), h ≥ 0; ``None`` skips a check."""
    out = []
    if a is not None:
        av = _finite_scalar("a", a)
        if av <= 0:
            raise ArgumentError("a", a, "gain must be > 0")
        out.append(av)
    if tau is not None:
        tv = _finite_scalar("tau", tau)
        if tv <= 0:
            raise ArgumentError("tau", tau, "window length in seconds must be > 0")
        out.append(tv)
    if h is not None:
        hv = _finite_scalar("h", h)
        if hv < 0:
            raise ArgumentError("h", h, "threshold must be >= 0")
        out.append(hv)
    return tuple(out)


def check_kernel(kernel: object) -> str:
    if kernel not in KERNELS:
        raise ArgumentError("kernel", kernel, f"allowed: {', '.join(KERNELS)}")
    return kernel  # type: ignore[return-value]


# dtype kinds of real numbers: float, signed and unsigned integer
_REAL_KINDS = "fiu"


def check_signal(strain: object, t: object, *, min_ndim: int = 1, t_prev: float | None = None,
                 check_finite: bool = True, check_times: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """``strain (..., n)`` finite, ``t (n,)`` finite and strictly increasing (after
    ``t_prev`` when a stream continues). Returns float64 arrays.

    ``check_finite=False`` skips the scan of the strain for NaN/inf; the kernels detect
    them in one pass instead (they persist in the running sums) and call back here.
    ``check_times=False`` leaves the scan of t to :func:`check_times_uniform`."""
    s = np.asarray(strain)
    if s.dtype.kind not in _REAL_KINDS:
        raise ArgumentError("strain", f"dtype {s.dtype}", "must be a real numeric array")
    s = s.astype(np.float64, copy=False)
    if s.ndim < min_ndim:
        raise ArgumentError("strain", f"shape {s.shape}",
                            f"needs at least {min_ndim} dimension(s): (..., "
                            + ("n_receptors, " if min_ndim > 1 else "") + "n_time)")
    tt = np.asarray(t)
    if tt.ndim != 1:
        raise ArgumentError("t", f"shape {tt.shape}", "must be one-dimensional (n_time,) in seconds")
    if tt.dtype.kind not in _REAL_KINDS:
        raise ArgumentError("t", f"dtype {tt.dtype}", "must be a real numeric array")
    tt = tt.astype(np.float64, copy=False)
    if tt.shape[0] != s.shape[-1]:
        raise ArgumentError("t", f"length {tt.shape[0]}",
                            f"must match the last axis of strain (n_time = {s.shape[-1]})")
    if check_times:
        i = _first_bad_time(tt)
        if i >= 0:
            _raise_bad_time(tt, i)
    if t_prev is not None and tt.shape[0] and tt[0] <= t_prev:
        raise ArgumentError("t", f"{tt[0]} at the chunk start",
                            f"must continue after the previous chunk's last time {t_prev}")
    if check_finite and not np.isfinite(s).all():
        idx = np.unravel_index(int(np.argmax(~np.isfinite(s))), s.shape)
        raise ArgumentError("strain", f"{s[idx]} at index {tuple(int(i) for i in idx)}",
                            "samples must be finite (no NaN or inf)")
    return s, tt


def _raise_bad_time(t: np.ndarray, i: int) -> None:
    if not np.isfinite(t[i]):
        raise ArgumentError("t", f"{t[i]} at index {i}", "must be finite")
    raise ArgumentError("t", f"{t[i]} at index {i} after {t[i - 1]}", "must be strictly increasing")


def check_weights(weights: object, n_receptors: int) -> np.ndarray:
    w = np.asarray(weights, dtype=np.float64)
    if w.ndim != 1 or w.shape[0] != n_receptors:
        raise ArgumentError("weights", f"shape {w.shape}",
                            f"must be ({n_receptors},), one weight per receptor (axis -2 of strain)")
    if not np.isfinite(w).all():
        raise ArgumentError("weights", w.tolist(), "must be finite")
    return w


@nb.njit(cache=True, nogil=True)
def _first_bad_time(t):
    """Index of the first non-finite or non-increasing time, or −1."""
    if t.shape[0] and not math.isfinite(t[0]):
        return 0
    for i in range(1, t.shape[0]):
        if not (t[i] - t[i - 1] > 0.0) or not math.isfinite(t[i]):
            return i
    return -1


# relative spread of the sampling interval below which a record counts as uniform
UNIFORM_RTOL = 1e-9


def uniform_grid(t: np.ndarray) -> tuple[float, float] | None:
    """(Δt, tolerance) of the uniform grid implied by the ends of ``t`` (float64, 1-D,
    not empty; Δt = 0 for one sample), or None when an end is not finite. A record is
    uniform when every step is within the tolerance of Δt: 1e-9·Δt, or the rounding of
    the time stamps themselves (a few ulp of the largest |t|: 10⁷ samples at 1 ms carry
    ~2e-12 s)."""
    if not (math.isfinite(t[0]) and math.isfinite(t[-1])):
        return None
    t0, t1 = float(t[0]), float(t[-1])
    dt = (t1 - t0) / (t.shape[0] - 1) if t.shape[0] >= 2 else 0.0
    return dt, UNIFORM_RTOL * abs(dt) + 4 * math.ulp(max(abs(t0), abs(t1)))


def check_times_uniform(t: np.ndarray, grid: tuple[float, float] | None = None) -> float | None:
    """Check ``t`` (float64, 1-D) like :func:`check_signal` does and return its sampling
    interval when it is uniform (see :func:`uniform_grid`; ``grid`` if already known),
    else None. One vectorised pass when t is on its grid; a second one finds the first
    bad time otherwise."""
    n = t.shape[0]
    if grid is None and n:
        grid = uniform_grid(t)
    if grid is not None and grid[1] < grid[0] and steps_off_grid(t, *grid) == 0:
        return grid[0]
    i = _first_bad_time(t)
    if i >= 0:
        _raise_bad_time(t, i)
    return grid[0] if n == 2 else None
