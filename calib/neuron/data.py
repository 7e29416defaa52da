"""Labelled plate scans for M2: the record a fit starts from."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from feeler.calib.neuron.model import PeakTable, peak_table

__all__ = ["NeuronData", "data_from_scans", "shared_times"]


@dataclass(frozen=True)
class NeuronData:
    """Labelled scans for M2.

    Attributes:
        strain (ndarray[n_scans, n_time]): U_y / length, dimensionless.
        t_s (ndarray[n_time] | ndarray[n_scans, n_time]): sample times, s: one time
            base shared by every scan, or each scan's own (acquired scans record when
            each sample was actually taken).
        step_mm (ndarray[n_scans]): label of each scan (its plate's step), mm.
        length_mm (float): representative length used for the strain, mm.
        kernel (str): temporal window of the neuron.
        x_mm (ndarray[n_scans, n_time] | None): stage position, mm (for the units check).
        speed_mm_s (ndarray[n_scans] | None): commanded stage speed, mm/s (same).
        scan_names (tuple[str, ...] | None): how the checks name each scan (``scan_id 5``,
            ``scan_id 'touch-04'``, ``scan file scan_03.csv``; None: by its place in the data).
    """
    strain: np.ndarray
    t_s: np.ndarray
    step_mm: np.ndarray
    length_mm: float
    kernel: str = "boxcar"
    x_mm: np.ndarray | None = None
    speed_mm_s: np.ndarray | None = None
    scan_names: tuple[str, ...] | None = None

    def table(self, n_grid: int = 256) -> PeakTable:
        """Peak u₁ on a log-τ grid from one sample interval to half the scan duration.

        A shorter window sees a single backward difference, the raw rate that the paper
        shows cannot order the plates (Fig. 8): with a few touches per plate it can look
        tight by chance (all snaps, no rides) and decode fresh touches badly."""
        t = np.atleast_2d(self.t_s)
        dt = float(np.median(np.diff(t, axis=-1)))
        span = float(np.min(t[:, -1] - t[:, 0]))
        return peak_table(self.strain, self.t_s, tau_lo_s=dt, tau_hi_s=span / 2,
                          n_grid=n_grid, kernel=self.kernel)


def data_from_scans(scans, *, length_mm: float, kernel: str = "boxcar") -> NeuronData:
    """:class:`NeuronData` from a :class:`feeler.datasets.Scans` (each scan's own times;
    one shared row when they all agree)."""
    from feeler.datasets import strain

    t = shared_times(scans.t_s)
    return NeuronData(strain=strain(scans.uy_mm, length_mm), t_s=t,
                      step_mm=np.asarray(scans.step_mm, float), length_mm=float(length_mm), kernel=kernel,
                      x_mm=np.asarray(scans.x_mm, float), speed_mm_s=np.asarray(scans.speed_mm_s, float),
                      scan_names=tuple(scans.label(k) for k in range(len(scans.scan_id))))


def shared_times(t_s) -> np.ndarray:
    """``t_s (ndarray[n_scans, n_time])`` as one row when every scan has the same times,
    else unchanged (each scan keeps its own)."""
    t = np.asarray(t_s, float)
    return t[0] if t.ndim == 2 and np.all(t == t[:1]) else t
