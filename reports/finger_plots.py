"""The paper's finger figures (Figs 3–6) and the skin ladder's trade plot, as matplotlib
figures: drawn by the report and saved as PNGs by ``feeler skin figures`` / ``skin ladder``.

Every function takes plain arrays and returns an undrawn figure (constrained layout);
the caller renders it (:func:`feeler.reports.model.make_figure` or ``savefig``).
"""
from __future__ import annotations

import numpy as np

from feeler.reports.model import log_axis, subplots

__all__ = ["fig3", "fig3_detail", "fig4", "fig5", "fig6", "ladder_trade", "mesh_name", "SPEED_STYLE", "speed_line"]

#: per speed index: (marker, line style, marker face) so that coinciding points stay visible
SPEED_STYLE = (("o", "-", "none"), ("s", "--", "full"), ("^", "-.", "none"), ("D", ":", "full"))


def speed_line(j: int, n: int) -> dict:
    """Line width and opacity of speed ``j`` of ``n``: the first speeds wide and pale, the
    last thin and opaque on top, so that a line lying on another shows as a dashed line
    inside a band (with equal widths the later line hid the earlier: an outside reader)."""
    wide = n - 1 - j
    return {"lw": 1.0 + 2.2 * wide, "alpha": 1.0 if wide == 0 else 0.4, "zorder": 2 + j}


def _per_speed(speeds, height_in=2.5):
    fig, axes = subplots(len(speeds), width_in=7.0 / max(len(speeds), 1), height_in=height_in, squeeze=False,
                         sharey=True)
    return fig, axes[0]


def fig3(runs, speeds):
    """ε_y at the corpuscle against time, one panel per speed, one line per step."""
    fig, axes = _per_speed(speeds)
    for ax, v in zip(axes, speeds):
        for k, r in enumerate(r for r in runs if r.speed_mm_s == v):
            ax.plot(r.t_s, r.eps_y, lw=0.9, color=f"C{k}", label=f"{r.step_um:g} µm")
        ax.set(title=f"{v:g} mm/s", xlabel="t (s)")
        ax.legend(fontsize=6, title="step", title_fontsize=6)
    axes[0].set_ylabel("ε_y at the corpuscle")
    fig.suptitle("Fig. 3 — normal strain at the corpuscle: press, hold, slide", fontsize=9)
    return fig


def fig3_detail(runs, speeds, step_mm: float, half_window_mm: float = 1.5):
    """Δε_y from the pressed state while the corpuscle passes the step (|x − step| ≤ window)."""
    fig, axes = _per_speed(speeds)
    for ax, v in zip(axes, speeds):
        for k, r in enumerate(r for r in runs if r.speed_mm_s == v):
            s = r.slide_start
            near = np.flatnonzero(np.abs(r.x_mm[s:] - step_mm) <= half_window_mm) + s
            if near.size:
                ax.plot(r.t_s[near], r.eps_y[near] - r.eps_y[s], lw=0.9, color=f"C{k}", label=f"{r.step_um:g} µm")
        ax.set(title=f"{v:g} mm/s", xlabel="t (s)")
        ax.legend(fontsize=6, title="step", title_fontsize=6)
    axes[0].set_ylabel("Δε_y from the pressed state")
    fig.suptitle(f"Fig. 3 (detail) — the two spikes as the step passes (±{half_window_mm:g} mm)", fontsize=9)
    return fig


def fig4(runs, speeds, z_norm, tau_s: float):
    """Normalised pulse density against time (z / peak z at the fastest speed and highest step)."""
    fig, axes = _per_speed(speeds)
    for ax, v in zip(axes, speeds):
        for k, ((t, z), r) in enumerate((tz, r) for tz, r in zip(z_norm, runs) if r.speed_mm_s == v):
            ax.plot(t, z, lw=0.9, color=f"C{k}", label=f"{r.step_um:g} µm")
        ax.set(title=f"{v:g} mm/s", xlabel="t (s)")
        ax.legend(fontsize=6, title="step", title_fontsize=6)
    axes[0].set_ylabel("normalised pulse density")
    fig.suptitle(f"Fig. 4 — normalised pulse density, τ = {tau_s * 1e3:g} ms", fontsize=9)
    return fig


def fig5(heights, speeds, peaks, fits=None):
    """Peak pulse density against step height per speed, with the least-squares lines.

    Args:
        heights (ndarray[n_h]) µm; speeds (ndarray[n_v]) mm/s; peaks (ndarray[n_h, n_v]);
        fits: per speed (slope per µm, intercept, R²) or None to fit here.
    """
    fig, ax = subplots(width_in=4.2, height_in=3.0)
    for j, v in enumerate(speeds):
        marker, ls, face = SPEED_STYLE[j % len(SPEED_STYLE)]
        slope, icpt, r2 = fits[j] if fits is not None else (*np.polyfit(heights, peaks[:, j], 1), np.nan)
        ax.plot(heights, peaks[:, j], marker, color=f"C{j}", ms=7 - 2 * j, mfc="none" if face == "none" else f"C{j}",
                ls="none", label=f"{v:g} mm/s")
        ax.plot(heights, slope * np.asarray(heights) + icpt, ls, color=f"C{j}", **speed_line(j, len(speeds)),
                label=f"line, {v:g} mm/s (R² = {r2:.4f})")
    ax.set(xlabel="step height (µm)", ylabel="peak pulse density (normalised)",
           title="Fig. 5 — peak z against step height")
    ax.legend(fontsize=6)
    return fig


def fig6(taus, heights, speeds, accepted, human=()):
    """Accepted against presented height for each τ and speed, the human PSEs as points.

    Args:
        taus (ndarray[n_tau]) s; accepted (ndarray[n_tau, n_h, n_v]) µm;
        human: (presented µm, PSE µm, lo, hi, speed mm/s, label) per point.
    """
    if not len(human):
        fig, ax = subplots(width_in=6.6, height_in=3.2)
        _fig6_lines(ax, taus, heights, speeds, accepted)
        fig.legend(*ax.get_legend_handles_labels(), loc="outside right upper", fontsize=6, frameon=False)
        return fig
    fig, (ax, zoom) = subplots(2, width_in=3.3, height_in=3.2, width_ratios=(2.6, 1.0))
    for a in (ax, zoom):
        _fig6_lines(a, taus, heights, speeds, accepted)
        _human_stars(a, human, speeds, ms=9 if a is ax else 6)
    x0, x1, y0, y1 = _around(human)
    zoom.set(xlim=(x0, x1), ylim=(y0, y1), xlabel="presented (µm)", ylabel="", title="human PSEs, zoomed")
    zoom.title.set_fontsize(7)
    ax.add_patch(_box(x0, x1, y0, y1))
    fig.legend(*ax.get_legend_handles_labels(), loc="outside lower center", ncol=3, fontsize=6, frameon=False)
    return fig


def _fig6_lines(ax, taus, heights, speeds, accepted) -> None:
    """Fig. 6's line per τ and speed (:func:`speed_line`) and the identity line on top."""
    for k, tau in enumerate(taus):
        for j, v in enumerate(speeds):
            marker, ls, _ = SPEED_STYLE[j % len(SPEED_STYLE)]
            ax.plot(heights, accepted[k, :, j], ls, marker=marker, ms=3, color=f"C{k % 10}",
                    **speed_line(j, len(speeds)), label=f"τ = {tau * 1e3:g} ms, {v:g} mm/s")
    lim = [min(heights), max(heights)]
    ax.plot(lim, lim, ":", color="k", lw=0.8, zorder=2 + len(speeds), label="accepted = presented")
    ax.set(xlabel="presented step height (µm)", ylabel="accepted step height (µm)",
           title="Fig. 6 — accepted vs presented height")


def _human_stars(ax, human, speeds, ms: float) -> None:
    for x, pse, lo, hi, v, label in human:
        j = int(np.argmin(np.abs(np.asarray(speeds) - v))) if len(speeds) else 0
        ax.errorbar([x], [pse], yerr=[[pse - lo], [hi - pse]], fmt="*", ms=ms, color="k", mfc="w" if j else "k",
                    capsize=3, elinewidth=1.2, zorder=10, label=label)


def _around(human, least_um: float = 0.5) -> tuple[float, float, float, float]:
    """(x0, x1, y0, y1): the human PSEs and their intervals with a margin, at least
    ``least_um`` either side (their intervals are narrower than a star on Fig. 6's scale)."""
    x = np.array([h[0] for h in human], float)
    y = np.array([v for h in human for v in h[1:4] if np.isfinite(v)], float)
    xm = max(least_um, 0.15 * np.ptp(x))
    ym = max(least_um, 0.25 * np.ptp(y))
    return x.min() - xm, x.max() + xm, y.min() - ym, y.max() + ym


def _box(x0, x1, y0, y1):
    from matplotlib.patches import Rectangle

    return Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, edgecolor="0.4", lw=0.7, zorder=11)


def mesh_name(mesh: str, converged: bool | None) -> str:
    """The study's finest mesh is named "converged" in its files; called so only when its
    convergence goal was met (``converged`` False: "finest"; None: not known, as named)."""
    return "finest" if mesh == "converged" and converged is False else mesh


def ladder_trade(rows, converged: bool | None = None):
    """Seconds per slide against the peak strain-rate error to the L2 reference, log–log.

    Args:
        rows: (level, mesh, seconds_per_slide, rate_error) per ladder rung; an error of
            0 (the reference itself) is drawn at the axis floor and said so.
        converged: the study's verdict on mesh convergence (ladder.json ``met``); False
            labels the "converged" mesh "finest" (:func:`mesh_name`).
    """
    fig, ax = subplots(width_in=5.6, height_in=3.0)
    errors = np.array([r[3] for r in rows], float)
    floor = max(np.min(errors[errors > 0]) / 3, 1e-6) if np.any(errors > 0) else 1e-4
    markers = {"l2": "s", "l1": "o", "l0": "^", "l0-fitted": "v"}
    for k, (level, mesh, secs, err) in enumerate(rows):
        name = mesh_name(mesh, converged)
        label = (f"{level.upper()} ({name}, reference)" if err <= 0 and converged is False else
                 f"{level.upper()} ({name})" + (" = reference" if err <= 0 else ""))
        ax.plot(secs, max(err, floor), markers.get(level, "D"), color=f"C{k % 10}", ms=6, label=label)
    log_axis(ax, "x")
    log_axis(ax, "y")
    ax.set(xlabel="seconds per slide", ylabel="peak strain-rate error vs L2 reference",
           title="Skin fidelity ladder: cost against error")
    fig.legend(*ax.get_legend_handles_labels(), loc="outside right upper", fontsize=6, frameon=False)
    return fig
