"""The robot-scan section: the paper's Figs 7–9 and the strain and peak figures for this run.

All curves are computed from ``four-plates/scans.csv`` with the neuron of
``four-plates/scene.toml`` (strain = U_y / representative length, paper §5.2); the
per-plate table is ``robot_table.json`` as written by ``feeler demo``.
"""
from __future__ import annotations

import numpy as np

from feeler.reports.model import Figure, Note, Section, Table, figure_uri, fmt, subplots
from feeler.reports.readers import read_json

__all__ = ["robot_section"]

SCENE, SCANS, TABLE = "four-plates/scene.toml", "four-plates/scans.csv", "robot_table.json"


def robot_section(inv, spec) -> Section:
    """Figures of one scan per plate (strain, ΔU_y, U̇_y, z) and peak z against step height."""
    from feeler.datasets import read_scans, strain
    from feeler.models import neuron
    from feeler.scene import load_scene
    from feeler.simulate import features_of

    scene = load_scene(inv.run_dir / SCENE)
    scans = read_scans(inv.run_dir / SCANS)
    nrn = scene.neuron
    eps = strain(scans.uy_mm, nrn.length_mm)
    z = neuron.per_time_base(lambda s, t: neuron.pulse_density(s, t, a=nrn.a, tau=nrn.tau_s, h=nrn.h,
                                                                kernel=nrn.kernel), eps, scans.t_s)
    peak_z = features_of(scene, scans).peak_z
    steps = list(dict.fromkeys(scans.step_mm.tolist()))
    first = [int(np.flatnonzero(scans.step_mm == s)[0]) for s in steps]
    t = scans.t_s                      # each scan's own sample times (n_scans, n_time)
    src = (SCANS, SCENE)
    neuron_words = (f"a = {fmt(nrn.a)} V s, τ = {fmt(nrn.tau_s)} s, h = {fmt(nrn.h)} V, "
                    f"length {fmt(nrn.length_mm)} mm ({nrn.kernel} window)")
    curves = [
        ("Strain history ε_y = U_y / length", "t (s)", "ε_y", lambda i: (t[i], eps[i])),
        ("Fig. 7: ΔU_y = U_y − U_y0", "x (mm)", "ΔU_y (mm)",
         lambda i: (scans.x_mm[i], scans.uy_mm[i] - scans.uy_mm[i, 0])),
        ("Fig. 8: rate of vertical displacement U̇_y", "t (s)", "U̇_y (mm/s)",
         lambda i: (t[i, 1:], np.diff(scans.uy_mm[i]) / np.diff(t[i]))),
        ("Fig. 9: pulse density z", "t (s)", "z (V)", lambda i: (t[i], z[i])),
    ]
    blocks = [Note(f"Scene {scene.scene.name}: {scene.scene.description}", sources=(SCENE,)),
              Note(f"{len(scans.scan_id)} scans, {len(steps)} plates; neuron {neuron_words}.",
                   sources=src)]
    for title, xlabel, ylabel, series in curves:
        fig, ax = subplots()
        for step, i in zip(steps, first):
            ax.plot(*series(i), label=f"δ = {step:g} mm (scan {scans.scan_id[i]})")
        ax.set(xlabel=xlabel, ylabel=ylabel, title=title)
        ax.legend(fontsize=7)
        blocks.append(Figure(title, figure_uri(fig), src, caption="First scan of each plate."))
    blocks.append(_peak_figure(scans.step_mm, peak_z, src))
    if inv.has(TABLE):
        blocks += _plate_tables(inv.run_dir / TABLE)
    return Section(spec.key, spec.title, tuple(blocks))


def _peak_figure(step_mm, peak_z, src) -> Figure:
    steps = np.unique(step_mm)
    mean = np.array([peak_z[step_mm == s].mean() for s in steps])
    sd = np.array([peak_z[step_mm == s].std(ddof=1) if (step_mm == s).sum() > 1 else 0.0 for s in steps])
    fig, ax = subplots()
    ax.plot(step_mm, peak_z, ".", alpha=0.4, label="each scan")
    ax.errorbar(steps, mean, yerr=sd, fmt="o-", capsize=3, label="mean ± sd")
    ax.set(xlabel="step height δ (mm)", ylabel="peak z (V)", title="Peak pulse density against step height")
    ax.legend(fontsize=7)
    return Figure("Peak pulse density against step height", figure_uri(fig), src,
                  caption="Peak of z over each scan (cf. the paper's Fig. 5 for the finger).")


def _plate_tables(path) -> list[Table]:
    from feeler.errors import DataFileError

    table = read_json(path, ("plates",))
    cols = ("step_mm", "n_scans", "peak_z_mean", "peak_z_sd", "raw_rate_mean_mm_s",
            "raw_rate_sd_mm_s", "jump_uy_mean_mm")
    try:
        rows = tuple(tuple(fmt(p[c]) for c in cols) for p in table["plates"])
        pairs = tuple((fmt(p["lower_mm"]), fmt(p["higher_mm"]), fmt(p["pc_peak_z"], 3),
                       fmt(p["pc_raw_rate"], 3)) for p in table.get("adjacent_pairs", ()))
    except (KeyError, TypeError) as exc:
        raise DataFileError(path, f"unexpected layout of the per-plate table ({exc!r})") from None
    plates = Table("Per plate: peak z, raw U̇_y and the ΔU_y jump", cols, rows, (TABLE,))
    if not pairs:
        return [plates]
    return [plates, Table("2AFC proportion correct of adjacent plates",
                          ("lower_mm", "higher_mm", "pc by peak z", "pc by raw U̇_y peak"), pairs, (TABLE,))]
