"""The finger section: the paper's Figs 3–6 for the finger and the skin fidelity ladder.

From a finger-steps part (``strain.csv`` + ``scene.toml``): Fig. 3 (strain histories and
their detail at the step), Fig. 4 (normalised pulse density), Fig. 5 (peak against step
height at every speed, with its lines), Fig. 6 (accepted against presented height over
the τ sweep, with the human PSEs). A ``feeler skin figures`` directory without the
histories gives Figs 5–6 from its CSVs. A ladder part (``trade.csv``, ``convergence.csv``,
``ladder.json``) gives the trade plot and its tables.
"""
from __future__ import annotations

import numpy as np

from feeler.reports import finger_plots as fp
from feeler.reports.fingerdata import finger_data
from feeler.reports.humandata import human_data
from feeler.reports.model import Note, Section, Table, fmt, make_figure, table_from_frame
from feeler.reports.readers import run_json, run_table

__all__ = ["finger_section", "finger_inputs", "human_points", "ladder_blocks", "ladder_files", "fig6_caption",
           "LINES_CAPTION", "LADDER_COLUMNS"]

#: trade.csv's columns, and those that must be numbers
LADDER_COLUMNS = (("level", "mesh", "seconds_per_slide", "rate_error"), ("seconds_per_slide", "rate_error"))
_FIG5 = ("step_um", "speed_mm_s", "peak_z_norm")
_FIG6 = ("tau_s", "step_um", "speed_mm_s", "accepted_um")


def ladder_files(inv, part) -> tuple:
    """(trade.csv, ladder.json or {}) of a ladder part, read once per report."""
    trade = run_table(inv, part.path("trade.csv"), *LADDER_COLUMNS)
    info = run_json(inv, part.path("ladder.json")) if inv.has(part.path("ladder.json")) else {}
    return trade, info


def finger_inputs(inv, spec) -> None:
    """Read what the section draws before the report's first figure: the strain histories
    and their scene (or a `feeler skin figures` directory's tables), the human PSEs of
    Fig. 6, and each ladder's files."""
    human_data(inv)
    if finger_data(inv) is None:
        figs = next((p for p in spec.parts if p.kind == "skin-figures"), None)
        if figs is not None and "fig5_peaks.csv" in figs.files:
            run_table(inv, figs.path("fig5_peaks.csv"), _FIG5, _FIG5)
        if figs is not None and "fig6_accepted.csv" in figs.files:
            run_table(inv, figs.path("fig6_accepted.csv"), _FIG6, _FIG6)
    for part in (p for p in spec.parts if p.kind == "ladder"):
        ladder_files(inv, part)
        if inv.has(part.path("convergence.csv")):
            run_table(inv, part.path("convergence.csv"))


#: how Figs 5 and 6 keep a speed's line visible under another's (:func:`finger_plots.speed_line`)
LINES_CAPTION = ("a slower speed's line is drawn wider and paler under a faster one's, so where the speeds "
                 "coincide both show")


def fig6_caption(human: bool) -> str:
    """Fig. 6's caption; with human points, the zoomed panel that shows their intervals."""
    return ("κ(τ) · peak z for each τ of the sweep (κ = 1 / mean regression slope over the speeds, as in the "
            f"paper); {LINES_CAPTION}; dotted: accepted = presented."
            + (" Stars: human PSEs with their 95 % intervals, which are narrower than a star at the left's scale: "
               "the right panel draws the grey box again, enlarged." if human else ""))


def human_points(inv) -> tuple[list, tuple]:
    """Fig. 6 symbols: per pooled condition (standard µm, PSE, lo, hi, standard speed, label)."""
    human = human_data(inv)
    if human.pooled is None:
        return [], ()
    tag = " (SYNTHETIC)" if human.label else ""
    pts = []
    for _, r in human.pooled.iterrows():
        std = human.standard_um(r)
        pse, lo, hi = (human.value(r, c).value for c in ("pse_um", "pse_lb_um", "pse_ub_um"))
        if np.isfinite(std) and np.isfinite(pse):
            v = float(r["standard_speed_mm_s"])
            pts.append((std, pse, lo, hi, v, f"human PSE{tag}, standard at {v:g} mm/s"))
    return pts, tuple(p for p in (human.thresholds_rel, human.trials_rel) if p)


def _from_histories(inv, fd) -> list:
    f, scene, src = fd.figures, fd.scene, fd.sources
    speeds = list(f.speeds_mm_s)
    level = f"skin {fd.level.upper()}"
    blocks = [Note(f"{len(fd.runs)} strain histories ({len(f.heights_um)} steps × {len(speeds)} speeds) at skin "
                   f"fidelity {fd.level.upper()}; neuron a = {fmt(scene.neuron.a)} V s, h = {fmt(scene.neuron.h)} V, "
                   f"τ = {scene.neuron.tau_s * 1e3:g} ms for Figs 4–5 and {', '.join(f'{t * 1e3:g}' for t in f.taus_s)} "
                   "ms for Fig. 6.", sources=src)]
    blocks.append(make_figure("Fig. 3: strain at the corpuscle", fp.fig3(fd.runs, speeds), src,
                              f"One line per step height ({level}); the press, the 1 s hold, then the slide."))
    blocks.append(make_figure("Fig. 3 (detail): the spikes at the step",
                              fp.fig3_detail(fd.runs, speeds, scene.steps.position_mm), src,
                              "Change from the pressed state while the corpuscle passes the step: a tension "
                              "spike, then a compression spike, growing with the step."))
    blocks.append(make_figure("Fig. 4: normalised pulse density",
                              fp.fig4(fd.runs, speeds, f.z_norm, scene.neuron.tau_s), src,
                              f"z from the end of the press on, normalised to the peak at {speeds[-1]:g} mm/s and "
                              f"{f.heights_um[-1]:g} µm (the paper's normalisation)."))
    fits = [(x.slope_per_um, x.intercept, x.r2) for x in f.fits]
    blocks.append(make_figure("Fig. 5: peak pulse density against step height",
                              fp.fig5(f.heights_um, f.speeds_mm_s, f.peak_z, fits), src,
                              "Peaks of Fig. 4 (a marker per speed, open or filled) with their least-squares "
                              "lines, one per speed; " + LINES_CAPTION + "."))
    pts, hsrc = human_points(inv)
    blocks.append(make_figure("Fig. 6: accepted against presented step height",
                              fp.fig6(f.taus_s, f.heights_um, f.speeds_mm_s, f.accepted_um, pts), src + hsrc,
                              fig6_caption(bool(pts))))
    rows = tuple((f"{t * 1e3:g}", fmt(c, 4), fmt(r, 4)) for t, c, r in zip(f.taus_s, f.conversion, f.speed_ratio))
    blocks.append(Table("Fig. 6 per τ: conversion factor and speed effect", ("τ (ms)", "κ (µm per unit z)",
                        f"slope {speeds[-1]:g} / {speeds[0]:g} mm/s"), rows, src))
    return blocks


def _from_figure_csvs(inv, part) -> list:
    blocks = [Note(f"{part.label} holds the outputs of `feeler skin figures` without the strain histories: "
                   "Figs 5–6 are drawn from its tables; Figs 3–4 need strain.csv "
                   "(`feeler simulate datasets-synthetic/finger-steps.toml`).")]
    if "fig5_peaks.csv" in part.files:
        rel = part.path("fig5_peaks.csv")
        t = run_table(inv, rel, _FIG5, _FIG5)
        h, v = np.unique(t["step_um"]), np.unique(t["speed_mm_s"])
        peaks = t.pivot_table(index="step_um", columns="speed_mm_s", values="peak_z_norm").to_numpy()
        blocks.append(make_figure("Fig. 5: peak pulse density against step height", fp.fig5(h, v, peaks), (rel,),
                                  "Peaks (a marker per speed, open or filled) with their least-squares lines, one "
                                  "per speed; " + LINES_CAPTION + "."))
    if "fig6_accepted.csv" in part.files:
        rel = part.path("fig6_accepted.csv")
        t = run_table(inv, rel, _FIG6, _FIG6)
        taus, h, v = (np.unique(t[c]) for c in _FIG6[:3])
        acc = np.full((len(taus), len(h), len(v)), np.nan)
        for r in t.itertuples(index=False):
            acc[np.searchsorted(taus, r.tau_s), np.searchsorted(h, r.step_um), np.searchsorted(v, r.speed_mm_s)] = r.accepted_um
        pts, hsrc = human_points(inv)
        blocks.append(make_figure("Fig. 6: accepted against presented step height", fp.fig6(taus, h, v, acc, pts),
                                  (rel,) + hsrc, fig6_caption(bool(pts))))
    return blocks


def ladder_blocks(inv, part) -> list:
    """The trade plot, the trade table, the mesh convergence and the goals of a ladder part."""
    rel = part.path("trade.csv")
    trade, info = ladder_files(inv, part)
    where = str(info.get("measured", "by `feeler skin ladder`" + (" --small" if info.get("small") else "")))
    met = info.get("met")
    converged = bool(met["convergence"]) if isinstance(met, dict) and "convergence" in met else None
    rows = [(r.level, r.mesh, r.seconds_per_slide, r.rate_error) for r in trade.itertuples(index=False)]
    shown = trade.assign(level=trade["level"].astype(str).str.upper(),
                         mesh=[fp.mesh_name(str(m), converged) for m in trade["mesh"]])
    finest = (" Mesh 'finest' is the study's finest, named 'converged' in its files: its convergence goal was NOT "
              "met." if converged is False and (trade["mesh"] == "converged").any() else "")
    blocks = [make_figure("The skin fidelity ladder: seconds per slide against error", fp.ladder_trade(rows, converged),
                          (rel,), "Error of the peak strain rate against the reference (L2 on the finest mesh)."),
              Note(f"Measured {where}; the reference is L2 on the finest mesh of the study. Seconds per slide "
                   "exclude each level's one-off setup (its own column).", level="measured", sources=(rel,)),
              table_from_frame(shown, title="Trade table", sources=(rel,), caption=finest.strip())]
    conv = part.path("convergence.csv")
    if inv.has(conv):
        blocks.append(table_from_frame(run_table(inv, conv), title="L2 mesh convergence", sources=(conv,)))
    if isinstance(met, dict):
        words = "; ".join(f"{k.replace('_', ' ')}: {'met' if v else 'NOT met'}" for k, v in met.items())
        size = info.get("size", "small" if info.get("small") else "full")
        caveat = "" if size == "full" else f" (the goals are set for the full study; this is the {size} one)"
        blocks.append(Note(f"Goals{caveat}: {words}.", sources=(part.path("ladder.json"),)))
    return blocks


def finger_section(inv, spec) -> Section:
    blocks = []
    fd = finger_data(inv)
    if fd is not None:
        blocks += _from_histories(inv, fd)
    else:
        figs = next((p for p in spec.parts if p.kind == "skin-figures"), None)
        if figs is not None:
            blocks += _from_figure_csvs(inv, figs)
    for part in (p for p in spec.parts if p.kind == "ladder"):
        blocks += ladder_blocks(inv, part)
    if not any(p.kind == "ladder" for p in spec.parts):
        blocks.append(Note("The skin fidelity ladder is not in this run (`feeler skin ladder --out DIR`)."))
    return Section(spec.key, spec.title, tuple(blocks))
