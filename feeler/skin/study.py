"""File-writing side of ``feeler skin``: the ladder study and the figures, as CSV/JSON/PNG."""
from __future__ import annotations

import csv
import math
from dataclasses import asdict
from pathlib import Path

from feeler.calib.progress import stage
from feeler.models.skin import SkinParams, StepProfile
from feeler.models.skin.ladder import converged_change, convergence_study, trade_table
from feeler.models.skin.mesh import MeshSpec
from feeler.rundir import write_json

__all__ = ["ladder_files", "figure_files", "ladder_setup", "run_ladder_study", "write_figures"]

GOALS = {"convergence_change": 0.01, "l1_speedup": 100.0, "l1_rate_error": 0.10, "l0_speedup": 1e4}


def ladder_files() -> list[str]:
    return ["convergence.csv", "trade.csv", "ladder.json", "ladder.png"]


def figure_files() -> list[str]:
    return ["fig3_strain.png", "fig3_detail.png", "fig4_pulse_density.png", "fig5_peak_vs_height.png", "fig6_accepted.png",
            "fig5_peaks.csv", "fig6_accepted.csv", "figures.json"]


def ladder_setup(small: bool, tiny: bool = False):
    """(base mesh, refinement factors, travel per step mm) of the full, the small or the
    tiny study (tiny: the small study's two coarsest meshes, what ``feeler demo`` measures)."""
    coarse = MeshSpec(h_contact_mm=0.05, h_corpuscle_mm=0.02, h_far_mm=1.5, grade=0.4)
    if tiny:
        return coarse, (1.0, 1.41), 0.05
    if small:
        return coarse, (1.0, 1.41, 2.0), 0.05
    return MeshSpec(), (0.5, 0.71, 1.0, 1.41, 2.0), 0.01


def run_ladder_study(out: Path, *, small: bool = False, tiny: bool = False, measured: str | None = None,
                     speed_mm_s: float = 20.0, profile: StepProfile = StepProfile(15.0),
                     progress: bool | None = False) -> dict:
    """Run both parts, write the files, return the summary (also in ladder.json).

    Args:
        small, tiny: the study's size (see :func:`ladder_setup`); full by default.
        measured: words saying when and where it was measured (kept in ladder.json).
        progress: None: a line per stage and per mesh on stderr (a bar on a terminal);
            True: the same, bar forced; False: silent.
    """
    params = SkinParams()
    base, factors, travel = ladder_setup(small, tiny)
    dt = travel / speed_mm_s
    stage(f"L2 mesh convergence over {len(factors)} meshes", progress)
    rows = convergence_study(params, profile, speed_mm_s, base=base, factors=factors, dt_s=dt, progress=progress)
    change = converged_change(rows)
    with open(out / "convergence.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["factor", "n_nodes", "h_contact_mm", "setup_s", "slide_s", "pressed_eps",
                    "peak_step_eps", "peak_rate_per_s"])
        for r in rows:
            s = r.summary
            w.writerow([r.factor, r.n_nodes, f"{r.h_contact_mm:.5g}", f"{r.setup_s:.4g}", f"{r.slide_s:.4g}",
                        f"{s.pressed_eps:.8g}", f"{s.peak_step_eps:.8g}", f"{s.peak_rate_per_s:.8g}"])
    meshes = {"converged": base.refined(factors[-1]), "coarsest": base.refined(factors[0])}
    if 1.0 in factors[1:-1]:
        meshes["default"] = base
    setup = {name: next(r.setup_s for r in rows if base.refined(r.factor) == spec) for name, spec in meshes.items()}
    stage("trade table: L0, L1 and L2 timed on the converged and coarsest meshes", progress)
    trade, fitted = trade_table(params, profile, speed_mm_s, meshes=meshes, reference="converged", setup_s=setup, dt_s=dt)
    with open(out / "trade.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["level", "mesh", "setup_s", "seconds_per_slide", "peak_rate_per_s", "rate_error"])
        for t in trade:
            w.writerow([t.level, t.mesh, f"{t.setup_s:.4g}", f"{t.seconds_per_slide:.4g}",
                        f"{t.peak_rate_per_s:.6g}", f"{t.rate_error:.4g}"])
    l2 = next(t for t in trade if t.level == "l2" and t.mesh == "converged")
    l1 = next(t for t in trade if t.level == "l1" and t.mesh == "converged")
    l0 = next(t for t in trade if t.level == "l0")
    size = "tiny" if tiny else "small" if small else "full"
    result = {"small": small or tiny, "size": size, "speed_mm_s": speed_mm_s, "step_um": profile.height_um,
              "measured": measured or f"by `feeler skin ladder` ({size} study)",
              "convergence_change": change, "goals": GOALS,
              "l1_speedup": l2.seconds_per_slide / l1.seconds_per_slide, "l1_rate_error": l1.rate_error,
              "l0_speedup": l2.seconds_per_slide / l0.seconds_per_slide,
              "l0_speedup_with_l2_setup": (l2.seconds_per_slide + l2.setup_s) / l0.seconds_per_slide,
              "l0_fitted": {"l0_gain": fitted.l0_gain, "l0_base": fitted.l0_base},
              "convergence": [asdict(r) for r in rows], "trade": [asdict(t) for t in trade]}
    result["met"] = {"convergence": change["peak_step_eps"] < GOALS["convergence_change"],
                     "l1_speedup": result["l1_speedup"] >= GOALS["l1_speedup"],
                     "l1_rate_error": l1.rate_error <= GOALS["l1_rate_error"],
                     "l0_speedup": result["l0_speedup"] >= GOALS["l0_speedup"]}
    result["lines"] = [f"change between the two finest meshes: peak step strain {change['peak_step_eps']:.3%}, "
                       f"pressed strain {change['pressed_eps']:.3%}, peak strain rate {change['peak_rate_per_s']:.3%}",
                       *(f"{t.level:>9} {t.mesh:>11}: {t.seconds_per_slide:9.4g} s/slide (setup {t.setup_s:.3g} s), "
                         f"peak-rate error {t.rate_error:.2%}" for t in trade),
                       f"L1 speed-up {result['l1_speedup']:.3g}x, L0 speed-up {result['l0_speedup']:.3g}x "
                       f"({result['l0_speedup_with_l2_setup']:.3g}x counting L2 setup)",
                       f"L0 fitted to converged L2: gain {fitted.l0_gain:.4g}, base shift {fitted.l0_base:.4g}",
                       "goals" + ("" if size == "full" else f" (set for the full study; this is the {size} one)")
                       + ": " + "; ".join(f"{k.replace('_', ' ')} {'met' if v else 'NOT met'}"
                                          for k, v in result["met"].items())]
    write_json(out / "ladder.json", result)
    _plot_trade(trade, out / "ladder.png", converged=bool(result["met"]["convergence"]))
    return result


def unmet_goals(result: dict) -> list[str]:
    """The goals a full-size study missed, as "name (measured, goal ...)"; none for a small or tiny study.

    The goals are set for the full study's meshes and time steps: a coarse study's L2 is itself
    fast, so its speed-ups say nothing about them.
    """
    if result.get("size") != "full":
        return []
    measured = {"convergence": ("convergence_change", result["convergence_change"]["peak_step_eps"], "below"),
                "l1_speedup": ("l1_speedup", result["l1_speedup"], "at least"),
                "l1_rate_error": ("l1_rate_error", result["l1_rate_error"], "at most"),
                "l0_speedup": ("l0_speedup", result["l0_speedup"], "at least")}
    return [f"{name.replace('_', ' ')} {value:.3g} (goal {how} {GOALS[key]:.3g})"
            for name, (key, value, how) in measured.items() if not result["met"][name]]


def _plot_trade(trade, path: Path, *, converged: bool | None = None) -> None:
    """The ladder's trade figure; ``converged``: the study's verdict on mesh convergence (its
    finest mesh is labelled converged only when it is)."""
    import matplotlib.pyplot as plt

    from feeler.reports.finger_plots import ladder_trade
    from feeler.reports.model import report_style

    with report_style():
        fig = ladder_trade([(t.level, t.mesh, t.seconds_per_slide, t.rate_error) for t in trade], converged)
        fig.savefig(path, dpi=110)
    plt.close(fig)


def _finite_or_null(obj):
    """``obj`` with every non-finite number (NaN, ±inf: not JSON) as None (JSON null)."""
    import numpy as np

    if isinstance(obj, dict):
        return {k: _finite_or_null(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple, np.ndarray)):
        return [_finite_or_null(v) for v in obj]
    if isinstance(obj, (float, np.floating)):
        return float(obj) if math.isfinite(obj) else None
    return obj


def write_figures(scene, out: Path, *, level: str | None = None, progress: bool | None = False) -> list[str]:
    """Figs 3–6 for a finger-steps scene into ``out``; returns printable summary lines.
    ``progress`` as in :func:`run_ladder_study`."""
    from feeler.simulate.finger import finger_runs
    from feeler.skin.figures import figure_data, plot_figures

    level = scene.model.level if level is None else level
    runs = finger_runs(scene, level=level, progress=progress)
    stage("Figs 4-6: pulse densities and accepted heights over the tau sweep", progress)
    data = figure_data(runs, scene.neuron, scene.loading.press_s)
    stage(f"plotting Figs 3-6 into {out}", progress)
    plot_figures(runs, data, out, label=f"skin {level.upper()}", tau_s=scene.neuron.tau_s,
                 step_mm=scene.steps.position_mm)
    with open(out / "fig5_peaks.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["step_um", "speed_mm_s", "peak_z_norm"])
        for i, h in enumerate(data.heights_um):
            for j, v in enumerate(data.speeds_mm_s):
                w.writerow([h, v, f"{data.peak_z[i, j]:.8g}"])
    with open(out / "fig6_accepted.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["tau_s", "step_um", "speed_mm_s", "accepted_um"])
        for k, tau in enumerate(data.taus_s):
            for i, h in enumerate(data.heights_um):
                for j, v in enumerate(data.speeds_mm_s):
                    w.writerow([tau, h, v, f"{data.accepted_um[k, i, j]:.6g}"])
    summary = {"level": level, "fig5": [asdict(f) for f in data.fits],
               "fig6": {"tau_s": data.taus_s, "conversion_um": data.conversion,
                        "speed_slope_ratio": data.speed_ratio}}
    write_json(out / "figures.json", _finite_or_null(summary))
    lines = [f"Fig 5 at {f.speed_mm_s:g} mm/s: slope {f.slope_per_um:.4g} per µm, "
             + (f"R² = {f.r2:.4f}" if math.isfinite(f.r2) else "R² undefined (the peaks do not vary with height)")
             for f in data.fits]
    lines += [f"Fig 6 tau = {t * 1e3:g} ms: conversion {c:.4g} µm per unit z, slope ratio "
              f"{data.speeds_mm_s[-1]:g}/{data.speeds_mm_s[0]:g} mm/s = {r:.3f}"
              for t, c, r in zip(data.taus_s, data.conversion, data.speed_ratio)]
    return lines
