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
    ref = peaks[-1, -1]
    z_norm = [(t, z / ref) for t, z in z_runs]
    peaks = peaks / ref
    fits = []
    for j, v in enumerate(speeds):
        slope, icpt = np.polyfit(heights, peaks[:, j], 1)
        resid = peaks[:, j] - (slope * heights + icpt)
        r2 = 1 - np.sum(resid ** 2) / np.sum((peaks[:, j] - peaks[:, j].mean()) ** 2)
        fits.append(Fig5Fit(float(v), float(slope), float(icpt), float(r2)))
    taus = np.asarray(neuron.tau_sweep_s, dtype=float)
    accepted, kappa, ratio = np.zeros((len(taus), len(heights), len(speeds))), np.zeros(len(taus)), np.zeros(len(taus))
    for k, tau in enumerate(taus):
        pk = np.zeros((len(heights), len(speeds)))
        for i, h in enumerate(heights):
            for j, v in enumerate(speeds):
                t, e = _hold_on(index[(h, v)], press_s)
                pk[i, j] = max(neuron.a * peak_window_sum(e, t, tau=tau, kernel=neuron.kernel) - neuron.h, 0.0)
        slopes = heights @ pk / (heights @ heights)          # least squares through the origin
        kappa[k] = 1.0 / slopes.mean()
        accepted[k] = kappa[k] * pk
        ratio[k] = slopes[-1] / slopes[0]
    return FigureData(heights, speeds, z_norm, peaks, fits, taus, accepted, kappa, ratio)


def plot_figures(runs, data: FigureData, out_dir, *, label: str) -> list:
    """Write fig3_strain.png … fig6_accepted.png into ``out_dir``; returns the paths."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    paths = []
    n_v = len(data.speeds_mm_s)
    fig, axes = plt.subplots(2, n_v, figsize=(5 * n_v, 6.4), squeeze=False)
    for j, v in enumerate(data.speeds_mm_s):
        ax, zoom = axes[0, j], axes[1, j]
        for r in runs:
            if r.speed_mm_s == v:
                ax.plot(r.t_s, r.eps_y, lw=1, label=f"{r.step_um:g} µm")
                s = r.slide_start
                zoom.plot(r.t_s[s:], r.eps_y[s:] - r.eps_y[s], lw=1, label=f"{r.step_um:g} µm")
        ax.set(title=f"Fig 3 — ε_y at the corpuscle, {v:g} mm/s", xlabel="time (s)", ylabel="ε_y")
        zoom.set(title="slide: change from the pressed state", xlabel="time (s)", ylabel="Δε_y")
        ax.legend(fontsize=7)
    paths.append(_save(fig, out_dir, "fig3_strain.png", label))
    fig, axes = plt.subplots(1, len(data.speeds_mm_s), figsize=(5 * len(data.speeds_mm_s), 3.6), squeeze=False)
    for n, ((t, z), r) in enumerate(zip(data.z_norm, runs)):
        j = int(np.searchsorted(data.speeds_mm_s, r.speed_mm_s))
        axes[0, j].plot(t, z, lw=1, label=f"{r.step_um:g} µm")
    for j, v in enumerate(data.speeds_mm_s):
        axes[0, j].set(title=f"Fig 4 — normalised pulse density, {v:g} mm/s", xlabel="time (s)", ylabel="z / z_ref")
        axes[0, j].legend(fontsize=7)
    paths.append(_save(fig, out_dir, "fig4_pulse_density.png", label))
    fig, ax = plt.subplots(figsize=(5, 3.8))
    for j, f in enumerate(data.fits):
        ax.plot(data.heights_um, data.peak_z[:, j], "o", label=f"{f.speed_mm_s:g} mm/s (R² = {f.r2:.4f})")
        ax.plot(data.heights_um, f.slope_per_um * data.heights_um + f.intercept, "-", lw=1)
    ax.set(title="Fig 5 — peak pulse density vs step height", xlabel="step height (µm)", ylabel="peak z (normalised)")
    ax.legend(fontsize=7)
    paths.append(_save(fig, out_dir, "fig5_peak_vs_height.png", label))
    fig, ax = plt.subplots(figsize=(5.5, 4.2))
    styles = ["-", "--", ":", "-."]
    for k, tau in enumerate(data.taus_s):
        for j, v in enumerate(data.speeds_mm_s):
            ax.plot(data.heights_um, data.accepted_um[k, :, j], styles[j % 4], marker="o", ms=3,
                    color=f"C{k % 10}", label=f"τ = {tau * 1e3:g} ms, {v:g} mm/s")
    ax.plot(data.heights_um, data.heights_um, "k-", lw=0.5)
    ax.set(title="Fig 6 — accepted vs presented step height", xlabel="presented (µm)", ylabel="accepted (µm)")
    ax.legend(fontsize=6, ncol=2)
    paths.append(_save(fig, out_dir, "fig6_accepted.png", label))
    return paths


def _save(fig, out_dir, name, label):
    fig.text(0.99, 0.01, label, ha="right", va="bottom", fontsize=6, color="0.4")
    fig.tight_layout()
    path = out_dir / name
    fig.savefig(path, dpi=110)
    import matplotlib.pyplot as plt
    plt.close(fig)
    return path
