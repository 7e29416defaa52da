"""The paper's Figs 3–6 from a ``finger-steps`` scene: numbers first, then the plots.

- Fig 3: strain ε_y at the corpuscle against time (two spikes as the step passes);
- Fig 4: pulse density z(t) with τ = ``neuron.tau_s``, normalised by the peak of the
  fastest speed at the highest step (the paper: 40 mm/s, 15 µm);
- Fig 5: peak z against step height per speed, with the linear fit and its R²;
- Fig 6: accepted against presented height for each τ of ``neuron.tau_sweep_s``: per
  speed the slope of peak z on height (regression through the origin), the conversion
  factor κ = 1 / mean slope (the paper's "mean value of the regression coefficient"),
  accepted height = κ · peak z.

The neuron sees the record from the end of the press on (the finger "stabilised", as in
the paper), so the press transient does not enter the window.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from feeler.errors import ArgumentError
from feeler.models.neuron import peak_window_sum, pulse_density

__all__ = ["Fig5Fit", "FigureData", "figure_data", "plot_figures"]


@dataclass(frozen=True)
class Fig5Fit:
    speed_mm_s: float
    slope_per_um: float
    intercept: float
    r2: float


@dataclass(frozen=True)
class FigureData:
    """Everything plotted. Arrays are indexed [height, speed] unless said otherwise."""

    heights_um: np.ndarray
    speeds_mm_s: np.ndarray
    z_norm: list                  # per run (heights outer): (t_s, z / z_ref)
    peak_z: np.ndarray            # [height, speed] at neuron.tau_s, normalised
    fits: list                    # Fig5Fit per speed
    taus_s: np.ndarray
    accepted_um: np.ndarray       # [tau, height, speed]
    conversion: np.ndarray        # κ per tau (µm per unit peak z)
    speed_ratio: np.ndarray       # slope(fastest) / slope(slowest) per tau


def _hold_on(run, press_s):
    keep = run.t_s >= press_s - 1e-12
    return run.t_s[keep], run.eps_y[keep]


def figure_data(runs, neuron, press_s: float) -> FigureData:
    """Compute Figs 4–6 from :func:`feeler.simulate.finger.finger_runs` output."""
    heights = np.array(sorted({r.step_um for r in runs}))
    speeds = np.array(sorted({r.speed_mm_s for r in runs}))
    index = {(r.step_um, r.speed_mm_s): r for r in runs}
    z_runs, peaks = [], np.zeros((len(heights), len(speeds)))
    for i, h in enumerate(heights):
        for j, v in enumerate(speeds):
            t, e = _hold_on(index[(h, v)], press_s)
            z = pulse_density(e, t, a=neuron.a, tau=neuron.tau_s, h=neuron.h, kernel=neuron.kernel)
            z_runs.append((t, z))
            peaks[i, j] = z.max()
    if heights.size < 2:
        raise ArgumentError("heights_um", heights.tolist(), "Fig 5 fits a line: needs at least 2 distinct heights")
    ref = peaks[-1, -1]
    if not ref > 0:
        raise ArgumentError("neuron.h", neuron.h, f"the pulse density never rises above the threshold h at the "
                                                  f"tallest step and fastest speed (tau = {neuron.tau_s:g} s): "
                                                  f"nothing to normalise Figs 4-5 by; lower neuron.h")
    z_norm = [(t, z / ref) for t, z in z_runs]
    peaks = peaks / ref
    fits = [_line_fit(float(v), heights, peaks[:, j]) for j, v in enumerate(speeds)]
    taus = np.asarray(neuron.tau_sweep_s, dtype=float)
    accepted, kappa, ratio = np.zeros((len(taus), len(heights), len(speeds))), np.zeros(len(taus)), np.zeros(len(taus))
    for k, tau in enumerate(taus):
        pk = np.zeros((len(heights), len(speeds)))
        for i, h in enumerate(heights):
            for j, v in enumerate(speeds):
                t, e = _hold_on(index[(h, v)], press_s)
                pk[i, j] = max(neuron.a * peak_window_sum(e, t, tau=tau, kernel=neuron.kernel) - neuron.h, 0.0)
        slopes = heights @ pk / (heights @ heights)          # least squares through the origin
        if not np.all(slopes > 0):
            slow = speeds[int(np.argmin(slopes))]
            raise ArgumentError("neuron.h", neuron.h, f"at tau = {tau:g} s the window sum at {slow:g} mm/s never "
                                                      f"rises above the threshold h: no Fig 6 slope; lower neuron.h")
        kappa[k] = 1.0 / slopes.mean()
        accepted[k] = kappa[k] * pk
        ratio[k] = slopes[-1] / slopes[0]
    return FigureData(heights, speeds, z_norm, peaks, fits, taus, accepted, kappa, ratio)


def _line_fit(speed_mm_s: float, heights: np.ndarray, peaks: np.ndarray) -> Fig5Fit:
    """Least-squares line of peak on height; R² NaN when the peaks do not vary (undefined)."""
    slope, icpt = np.polyfit(heights, peaks, 1)
    resid = peaks - (slope * heights + icpt)
    spread = np.sum((peaks - peaks.mean()) ** 2)
    r2 = 1 - np.sum(resid ** 2) / spread if spread > 0 else np.nan
    return Fig5Fit(speed_mm_s, float(slope), float(icpt), float(r2))


def _labelled(fig, label: str):
    """Put ``label`` (the skin level) in the suptitle, or after the single panel's title."""
    if getattr(fig, "_suptitle", None) is not None:
        fig._suptitle.set_text(f"{fig._suptitle.get_text()} ({label})")
    elif fig.axes:
        fig.axes[0].set_title(f"{fig.axes[0].get_title()} ({label})")
    return fig


def plot_figures(runs, data: FigureData, out_dir, *, label: str, tau_s: float, step_mm: float,
                 human=()) -> list[tuple]:
    """Write fig3_strain.png, fig3_detail.png, fig4_pulse_density.png, fig5_peak_vs_height.png
    and fig6_accepted.png into ``out_dir``: the report's finger figures, drawn the same way.

    Args:
        tau_s: the neuron window of Fig. 4; step_mm: where the step is (Fig. 3 detail);
        human: Fig. 6 symbols, (presented µm, PSE, lo, hi, speed mm/s, label) each.
    Returns:
        (path, layout problems) per figure (see :func:`feeler.reports.layout.check_figure`).
    """
    from feeler.reports.model import report_style

    speeds = list(data.speeds_mm_s)
    fits = [(f.slope_per_um, f.intercept, f.r2) for f in data.fits]
    with report_style():
        return _save_all(runs, data, out_dir, label, speeds, fits, tau_s, step_mm, human)


def _save_all(runs, data, out_dir, label, speeds, fits, tau_s, step_mm, human) -> list[tuple]:
    import matplotlib.pyplot as plt

    from feeler.reports import finger_plots as fp
    from feeler.reports.layout import check_figure

    figures = {"fig3_strain.png": fp.fig3(runs, speeds),
               "fig3_detail.png": fp.fig3_detail(runs, speeds, step_mm),
               "fig4_pulse_density.png": fp.fig4(runs, speeds, data.z_norm, tau_s),
               "fig5_peak_vs_height.png": fp.fig5(data.heights_um, data.speeds_mm_s, data.peak_z, fits),
               "fig6_accepted.png": fp.fig6(data.taus_s, data.heights_um, data.speeds_mm_s, data.accepted_um, human)}
    out = []
    for name, fig in figures.items():
        _labelled(fig, label)
        fig.set_dpi(110)
        fig.canvas.draw()
        problems = check_figure(fig)
        fig.savefig(out_dir / name, dpi=110)
        plt.close(fig)
        out.append((out_dir / name, problems))
    return out
