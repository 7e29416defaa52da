"""The robot-scan section of one scan directory (simulated or acquired): the paper's
Figs 7–9 and the peak pulse density against the step, per-plate numbers, and for an
acquisition its counts and how late each sample was taken.

Curves are computed from the part's ``scans.csv`` (each scan with its own sample times)
with the neuron of :mod:`feeler.reports.robotdata`. A scan directory whose scene differs
from an earlier one's only by the seed (the demo's held-out scans) gets the table only.
"""
from __future__ import annotations

import numpy as np

from feeler.reports.model import Figure, Note, Section, Table, fmt, interval, make_figure, subplots
from feeler.reports.robotdata import robot_data

__all__ = ["robot_section", "robot_inputs", "plate_rows"]


MAX_CURVES = 8          # plates drawn as curves in Figs 7-9 (a legend entry each)


def plate_rows(rd, where: tuple = ()) -> tuple:
    """Per plate: (``where``,) step, scans, peak z mean ± sd, raw U̇_y peak mean ± sd, ΔU_y jump mean."""
    rows = []
    for s in rd.steps:
        m = rd.scans.step_mm == s
        sd = (lambda v: np.std(v, ddof=1) if v.size > 1 else np.nan)
        rows.append((*where, fmt(s), str(int(m.sum())), f"{fmt(rd.peak_z[m].mean())} ± {fmt(sd(rd.peak_z[m]), 2)}",
                     f"{fmt(rd.peak_rate_uy_mm_s[m].mean())} ± {fmt(sd(rd.peak_rate_uy_mm_s[m]), 2)}",
                     fmt(np.mean(rd.jump_uy_mm[m]))))
    return tuple(rows)


def _pairs_table(rd, src) -> Table:
    from feeler.datasets import proportion_correct
    from feeler.reports.stats import pc_interval

    rows = []
    for lo, hi in zip(sorted(rd.steps)[:-1], sorted(rd.steps)[1:]):
        a, b = rd.scans.step_mm == lo, rd.scans.step_mm == hi
        cells = []
        for v in (rd.peak_z, rd.peak_rate_uy_mm_s):
            pc = proportion_correct(v[a], v[b])
            cells.append(interval(pc, *pc_interval(v[a], v[b])))
        rows.append((fmt(lo), fmt(hi), *cells))
    return Table("Empirical 2AFC proportion correct of adjacent plates, from these scans (95 % bootstrap intervals "
                 "over scans)",
                 ("lower mm", "higher mm", "by peak z", "by raw U̇_y peak"), tuple(rows), src,
                 caption="P(the higher plate's scan gives the larger value) over all pairs of this run's simulated "
                         "scans. Not the model-based P(correct) of the discrimination section (M3), which draws fresh "
                         "touches from the calibrated model: the two estimate different things and need not agree.")


def _figures(rd, src) -> list[Figure]:
    s, t = rd.scans, rd.scans.t_s
    ref = max(float(rd.z[rd.first[-1]].max()), np.finfo(float).tiny)
    fig, (a7, a8) = subplots(2, height_in=2.4)
    fig2, (a9, ap) = subplots(2, height_in=2.4)
    # at most MAX_CURVES plates' curves, evenly spaced over the steps (18 plates' legends were
    # cut at the panels' edges, and colours repeat after 10)
    every = np.unique(np.round(np.linspace(0, len(rd.steps) - 1, min(len(rd.steps), MAX_CURVES))).astype(int))
    few = "" if every.size == len(rd.steps) else f" ({every.size} of the {len(rd.steps)} plates, evenly spaced)"
    for k, (step, i) in enumerate((rd.steps[j], rd.first[j]) for j in every):
        label, c = f"δ = {step:g} mm", f"C{k}"
        a7.plot(s.x_mm[i], s.uy_mm[i] - s.uy_mm[i, 0], color=c, lw=1, label=label)
        a8.plot(t[i, 1:], np.diff(s.uy_mm[i]) / np.diff(t[i]), color=c, lw=1, label=label)
        a9.plot(t[i], rd.z[i] / ref, color=c, lw=1, label=label)
    a7.set(xlabel="x (mm)", ylabel="ΔU_y = U_y − U_y0 (mm)", title="Fig. 7: vertical displacement")
    a8.set(xlabel="t (s)", ylabel="U̇_y (mm/s)", title="Fig. 8: rate of vertical displacement")
    a9.set(xlabel="t (s)", ylabel="Z = z / peak z (highest plate)", title="Fig. 9: normalised pulse density")
    steps = np.array(sorted(rd.steps))
    mean = np.array([rd.peak_z[s.step_mm == v].mean() for v in steps])
    sd = np.array([rd.peak_z[s.step_mm == v].std(ddof=1) if (s.step_mm == v).sum() > 1 else 0.0 for v in steps])
    ap.plot(s.step_mm, rd.peak_z, ".", color="0.6", ms=3, label="each scan")
    ap.errorbar(steps, mean, yerr=sd, fmt="o-", color="C3", capsize=3, ms=4, label="mean ± sd")
    ap.set(xlabel="step height δ (mm)", ylabel="peak z (V)", title="Peak pulse density against the step")
    for ax in (a7, a8, a9, ap):
        ax.legend(fontsize=6)
    return [make_figure("Figs 7 and 8: ΔU_y against x, U̇_y against t", fig, src,
                        f"First scan of each plate{few}, each on its own sample times."),
            make_figure("Fig. 9 and the peak pulse density against the step", fig2, src,
                        f"Left: z of the first scan of each plate{few}, normalised to the highest plate's peak "
                        "(paper Fig. 9). Right: peak z of every scan (cf. the finger's Fig. 5).")]


def _acquisition_blocks(rd, src) -> list:
    blocks = []
    if rd.summary:
        keys = ("scans_done", "scans_planned", "samples_written", "late_samples", "bad_frames", "bad_lines",
                "partial_lines_dropped", "aborted_attempts", "complete", "stopped", "stage", "camera", "c_source")
        rows = tuple((k.replace("_", " "), fmt(rd.summary[k])) for k in keys if k in rd.summary)
        blocks.append(Table("Acquisition counts", ("quantity", "value"), rows, (rd.part.path("summary.json"),)))
        if rd.summary.get("complete") is False:
            why = rd.summary.get("stopped") or "stopped without a word: killed, or the machine went down"
            blocks.append(Note(f"Incomplete acquisition: {rd.summary.get('scans_done', '?')} of "
                               f"{rd.summary.get('scans_planned', '?')} scans ({why}); "
                               "resume with `feeler acquire ... --resume`.", level="failed",
                               sources=(rd.part.path("summary.json"),)))
    if rd.timing is not None and len(rd.timing):
        fig, (ax, hx) = subplots(2)
        for k, (sid, g) in enumerate(rd.timing.groupby("scan_id", sort=False)):
            ax.plot(g["t_sched_s"], (g["t_s"] - g["t_sched_s"]) * 1e3, lw=0.6, color=f"C{k % 10}", alpha=0.7)
        ax.set(xlabel="time (s), as scheduled", ylabel="taken − scheduled (ms)", title="When each sample was taken")
        if "status_rtt_s" in rd.timing:
            hx.hist(rd.timing["status_rtt_s"].to_numpy(float) * 1e3, bins=30, color="C1")
            hx.set(xlabel="status query round trip (ms)", ylabel="samples", title="Stage status round trip")
        else:
            hx.set_visible(False)
        late = int(np.sum(rd.timing["late"].to_numpy(float) > 0))
        blocks.append(make_figure("Sample timing of the acquisition", fig, src,
                                  f"One line per scan; {late} of {len(rd.timing)} samples flagged late."))
    return blocks


def _tables(datas, srcs) -> list:
    """The per-plate table of every directory of the design (one column says which), and
    the adjacent-pair table of the first."""
    many = len(datas) > 1
    rows = sum((plate_rows(rd, (rd.part.label,) if many else ()) for rd in datas), ())
    short = not all(np.all(np.isfinite(rd.jump_uy_mm)) for rd in datas)
    blocks = [Table("Per plate: peak z, raw U̇_y peak and the ΔU_y jump",
                    (("directory",) if many else ()) + ("step mm", "scans", "peak z (V) mean ± sd",
                                                        "raw U̇_y peak (mm/s) mean ± sd", "ΔU_y jump (mm)"),
                    rows, tuple(s for src in srcs for s in src),
                    caption="– : the scans are too short for the jump's two windows." if short else "")]
    if len(datas[0].steps) > 1:
        blocks.append(_pairs_table(datas[0], srcs[0]))
    return blocks


def robot_inputs(inv, spec) -> None:
    """Read every scan directory of the section (scans, scene, an acquisition's summary),
    before the report's first figure; the section takes them from the inventory's cache."""
    for part in spec.parts:
        robot_data(inv, part)


def robot_section(inv, spec) -> Section:
    """Scan directories of one design: the paper's robot figures for the first, per-plate
    tables for each, acquisition facts."""
    part, *repeats = spec.parts
    rd = robot_data(inv, part)
    src = tuple(part.path(f) for f in part.files)
    n = rd.neuron
    blocks = [Note(f"{rd.name}: {rd.description}".rstrip(": "), sources=src[1:] or src),
              Note(f"{len(rd.scans.scan_id)} scans over {len(rd.steps)} plates. Neuron (from {n.source}): "
                   f"a = {fmt(n.a)} V s, τ = {fmt(n.tau_s)} s, h = {fmt(n.h)} V, strain = U_y / {fmt(n.length_mm)} mm "
                   f"({n.kernel} window).", sources=src)]
    if len(rd.steps) and rd.scans.t_s.shape[1] > 2:
        blocks += _figures(rd, src)
    if part.kind == "acquisition":
        blocks += _acquisition_blocks(rd, src)
    others = [robot_data(inv, p) for p in repeats]
    if others:
        blocks.append(Note(f"{', '.join(o.part.label for o in others)}: {sum(len(o.scans.scan_id) for o in others)} "
                           "more scans of the same design (another seed); their figures would repeat these.",
                           sources=tuple(o.part.path("scans.csv") for o in others)))
    blocks += _tables([rd, *others], [src, *(tuple(o.part.path(f) for f in o.part.files) for o in others)])
    return Section(spec.key, spec.title, tuple(blocks))
