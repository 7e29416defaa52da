"""The FA-I (Meissner) mechanoreceptive unit of the paper (Eqs 1–6), exactly as DESIGN §4.

For samples ε_k at times t_k (uniform or not):

- strain rate by causal backward difference, ε̇_k = (ε_k − ε_{k−1})/(t_k − t_{k−1}), ε̇_0 = 0;
- receptor output x_k = a·|ε̇_k|, held over (t_{k−1}, t_k];
- temporal summation with the boxcar w = 1 on [0, τ): u(t_k) = Σ_i w_i [X_i(t_k) − X_i(t_k − τ)],
  X the running integral of x, linear inside each interval (fractional τ/Δt is exact);
  or, with ``kernel="exponential"``, w(s) = e^(−s/τ): u(t_k) = ∫ e^(−(t_k − s)/τ) x(s) ds;
- pulse density z = max(u − h, 0).

u is linear in a, so everything is computed at unit gain (``window_sum`` → u₁) and
scaled; for a > 0 the peak of z over time is max(a·peak(u₁) − h, 0), which is the fast
path for inference (:func:`peak_window_sum` once per τ, :func:`peak_pulse_density` for
any number of (a, h)). Inputs of any float dtype are computed in float64.
"""
from __future__ import annotations

import numpy as np

from feeler.models.neuron.stream import FA1Stream
from feeler.models.neuron.unit import Engine
from feeler.models.neuron.validate import check_kernel, check_params

__all__ = ["pulse_density", "window_sum", "peak_window_sum", "peak_pulse_density", "FA1Stream",
           "per_time_base"]


def window_sum(strain, t, *, tau: float, weights=None, kernel: str = "boxcar") -> np.ndarray:
    """Unit-gain membrane potential u₁ (u = a·u₁).

    Args:
        strain (ndarray[..., n_time] or ndarray[..., n_receptors, n_time] with weights):
            compressive strain samples ε, dimensionless.
        t (ndarray[n_time]): sample times in seconds, strictly increasing, not
            necessarily uniform.
        tau (float): window length τ in seconds, > 0 (time constant for the exponential kernel).
        weights (ndarray[n_receptors] | None): spatial summation weights w_i.
        kernel (str): ``"boxcar"`` (the paper's Eq. 4) or ``"exponential"``.

    Returns:
        ndarray[..., n_time] float64: u₁(t_k) (strain units).
    """
    (tau,) = check_params(tau=tau)
    return Engine(tau, check_kernel(kernel), weights).run(strain, t, whole=True)


def pulse_density(strain, t, *, a: float, tau: float, h: float, weights=None,
                  kernel: str = "boxcar") -> np.ndarray:
    """Pulse density z(t_k) = max(a·u₁(t_k) − h, 0) of the FA-I unit.

    Args:
        strain, t, tau, weights, kernel: as :func:`window_sum`.
        a (float): receptor gain, > 0 (output per unit strain rate).
        h (float): threshold, ≥ 0, in the units of u.

    Returns:
        ndarray[..., n_time] float64: z ≥ 0.

    Raises:
        ArgumentError: a ≤ 0, τ ≤ 0, h < 0, NaN/inf samples, non-increasing or
            mismatched ``t``, wrong weight length, unknown kernel.
    """
    a, tau, h = check_params(a=a, tau=tau, h=h)
    return Engine(tau, check_kernel(kernel), weights).run(strain, t, a=a, h=h, clamp=True,
                                                         whole=True)


def peak_window_sum(strain, t, *, tau: float, weights=None, kernel: str = "boxcar") -> np.ndarray:
    """max over time of u₁ — one window sum per τ serves a likelihood over any (a, h).

    Returns:
        ndarray[...] float64: the strain's shape without the time axis (and without the
        receptor axis when ``weights`` is given); 0 for an empty record.
    """
    u1 = window_sum(strain, t, tau=tau, weights=weights, kernel=kernel)
    if u1.shape[-1] == 0:
        return np.zeros(u1.shape[:-1])
    return u1.max(axis=-1)


def peak_pulse_density(peak_u1, a, h) -> np.ndarray:
    """Peak of z over time from the peak of u₁: max(a·peak_u1 − h, 0), broadcasting.

    Exact for a > 0 because max commutes with scaling by a > 0 and shifting by −h.
    ``a`` and ``h`` may be arrays (e.g. posterior draws) broadcast against ``peak_u1``.
    """
    a = np.asarray(a, dtype=np.float64)
    h = np.asarray(h, dtype=np.float64)
    for name, v, bad in (("a", a, ~(a > 0) | ~np.isfinite(a)), ("h", h, ~(h >= 0) | ~np.isfinite(h))):
        if bad.any():
            check_params(**{name: float(v[bad].flat[0])})
    peak_u1 = np.asarray(peak_u1, dtype=np.float64)
    try:
        np.broadcast_shapes(a.shape, h.shape, peak_u1.shape)
    except ValueError:
        from feeler.errors import ArgumentError

        raise ArgumentError("a, h", f"shapes {a.shape}, {h.shape}",
                            f"arrays that broadcast against peak_u1 of shape {peak_u1.shape}: draws for a "
                            f"batch of records as (n_draws, 1), giving (n_draws, n_records)") from None
    return np.maximum(a * peak_u1 - h, 0.0)


def per_time_base(fn, strain, t) -> np.ndarray:
    """Apply a batch function to records that each carry their own sample times.

    The neuron core takes one time axis per call. Acquired scans are sampled when the
    stage and camera actually answered, so each scan has its own times; this groups the
    records by identical time rows and calls ``fn(strain_group, t_row)`` once per group.

    Args:
        fn: e.g. ``lambda s, tt: peak_window_sum(s, tt, tau=0.5)``; returns an array whose
            leading axis is the group's records.
        strain (ndarray[n_records, n_time]): one record per row.
        t (ndarray[n_time] | ndarray[n_records, n_time]): shared or per-record times, s.
    Returns:
        ndarray: ``fn``'s results stacked in record order (leading axis n_records).
    """
    s = np.asarray(strain, dtype=np.float64)
    tt = np.asarray(t, dtype=np.float64)
    if tt.ndim == 1:
        return np.asarray(fn(s, tt))
    if s.ndim != 2 or tt.shape != s.shape:
        from feeler.errors import ArgumentError
        raise ArgumentError("t", f"shape {tt.shape}", f"(n_time,) or one row per record {s.shape}")
    if s.shape[0] == 0:
        return np.asarray(fn(s, tt[0] if len(tt) else np.empty(s.shape[1])))
    rows, inverse = np.unique(tt, axis=0, return_inverse=True)
    inverse = np.ravel(inverse)
    out = None
    for g in range(rows.shape[0]):
        members = np.flatnonzero(inverse == g)
        part = np.asarray(fn(s[members], rows[g]))
        if out is None:
            out = np.empty((s.shape[0],) + part.shape[1:], dtype=part.dtype)
        out[members] = part
    return out
