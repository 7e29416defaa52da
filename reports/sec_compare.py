"""Robot and human discrimination on one axis.

Order: the two functions on one axis, the table of thresholds and PSEs, the robot's
model-based P(correct) of its plate pairs, then the human data behind the fit.

Both psychometric functions are drawn as the 2AFC proportion correct against the height
difference on linear axes from 0, once in µm and once as a fraction of the reference (the
Weber fraction), with their difference thresholds (75 % correct) marked:

- robot: P(correct) that reference + Δ gives the larger response than the reference,
  from ``threshold_curve.csv`` (or the JSON's curve) with its 95 % band;
- human: the fitted cumulative normal through the pooled DT, P(correct) = Φ(z₇₅ Δ / DT)
  (lapse not drawn), its band from the DT's 95 % interval (a monotone map, so the band is
  exact), and for same-speed conditions the pooled data folded about the standard
  (P(correct) of comparisons |Δ| above or below it). Cross-speed conditions are drawn
  against the difference from their PSE.

Numbers from a fit that failed its verdict (the human's M4 fit, or the M2 fit behind the
robot's discrimination) are not results: their curves are not drawn, their table rows
are marked ``failed`` and say so (:data:`FAILED_FIT`), and a note names the fit.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from feeler.reports.discdata import pairs_frame, robot_disc
from feeler.reports.humandata import condition_words, human_data
from feeler.reports.model import Note, Section, Table, error_span, fmt, interval, make_figure, subplots

__all__ = ["compare_section", "compare_inputs", "Z75", "human_curve", "folded_points", "FAILED_FIT", "Shown"]

Z75 = 0.6744897501960817            # Φ⁻¹(0.75): DT = σ·z₇₅ for a cumulative normal
FAILED_FIT = "from a failed fit: see its verdict"


@dataclass(frozen=True)
class Shown:
    """Which fits' numbers are results: ``robot``/``human`` False when the fit they come
    from (M2 for the robot, M4 for the human) failed its verdict; ``notes`` say which."""
    robot: bool = True
    human: bool = True
    notes: tuple = ()


def _shown(inv, disc, human) -> Shown:
    from feeler.reports.readers import verdict_ok

    notes, robot, people = [], True, True
    m2 = inv.first("fit", "m2", prefer="m2")
    if disc is not None and verdict_ok(inv, m2) is False:
        robot = False
        notes.append(Note(f"The robot's threshold comes from the M2 fit in {m2.label}, which FAILED its "
                          f"verdict (see its section): its numbers below are marked '{FAILED_FIT}' and its curve "
                          "is not drawn.", level="failed", sources=(m2.path("verdict.json"),)))
    if human.pooled is not None and verdict_ok(inv, human.m4) is False:
        people = False
        notes.append(Note(f"The human thresholds come from the M4 fit in {human.m4.label}, which FAILED its "
                          f"verdict (see its section): their numbers below are marked '{FAILED_FIT}' and its curves "
                          "are not drawn.", level="failed", sources=(human.m4.path("verdict.json"),)))
    return Shown(robot, people, tuple(notes))


def human_curve(delta_um, dt_um):
    """Φ(z₇₅ Δ / DT): the 2AFC P(correct) of a cumulative normal with difference threshold DT."""
    from scipy.stats import norm

    return norm.cdf(Z75 * np.asarray(delta_um, float) / dt_um)


def folded_points(trials, standard_speed, comparison_speed):
    """(|Δ| µm, correct, trials) pooled over subjects for one same-speed condition: a
    comparison above the standard is correct when judged higher, below when judged lower."""
    t = trials[(trials["standard_speed_mm_s"] == standard_speed) & (trials["comparison_speed_mm_s"] == comparison_speed)]
    d = (t["comparison_um"] - t["standard_um"]).to_numpy(float)
    correct = np.where(d > 0, t["n_comparison_higher"], t["n_trials"] - t["n_comparison_higher"]).astype(float)
    keep = d != 0
    ad = np.round(np.abs(d[keep]), 9)
    levels = np.unique(ad)
    k = np.array([correct[keep][ad == v].sum() for v in levels])
    n = np.array([t["n_trials"].to_numpy(float)[keep][ad == v].sum() for v in levels])
    return levels, k, n


def _wilson(k, n, z=1.96):
    p = k / n
    c = (p + z * z / (2 * n)) / (1 + z * z / n)
    h = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return c - h, c + h


def _thresholds(disc, human, shown: Shown) -> tuple[float, float]:
    """The largest threshold shown, in µm and as a Weber fraction (to scale the axes)."""
    um, weber = [1.0], [0.05]
    if disc is not None and shown.robot and np.isfinite(disc.threshold_um.value):
        um.append(disc.threshold_um.value)
        weber.append(disc.threshold_um.value / disc.reference_um)
    if human.pooled is not None and shown.human:
        for _, r in human.pooled.iterrows():
            dt = human.value(r, "dt_um").value
            if np.isfinite(dt):
                um.append(dt)
                weber.append(dt / human.standard_um(r) if np.isfinite(human.standard_um(r)) else 0.0)
    return max(um), max(weber)


def _robot(ax, disc, scale: float) -> None:
    if disc.curve is not None:
        c = disc.curve
        ax.fill_between(c["delta_um"] * scale, c["lo95"], c["hi95"], color="C3", alpha=0.2, lw=0)
        label = f"robot at {fmt(disc.reference_um, 3)} µm" + (" (EXTRAPOLATED)" if disc.extrapolated else "")
        ax.plot(c["delta_um"] * scale, c["pc"], "-", color="C3", label=label)
    th = disc.threshold_um
    if np.isfinite(th.value):
        lo = th.lo if np.isfinite(th.lo) else th.value
        hi = th.hi if np.isfinite(th.hi) else th.value
        ax.errorbar([th.value * scale], [0.75], xerr=error_span([th.value * scale], [lo * scale], [hi * scale]),
                    fmt=">" if th.bound else "v", color="C3", ms=6, capsize=3, label=f"robot DT {th.text(3, 'µm')}")


def _human(ax, human, k, r, weber: bool, top_um: float) -> None:
    std, same = human.standard_um(r), float(r["standard_speed_mm_s"]) == float(r["comparison_speed_mm_s"])
    dt, lb, ub = (human.value(r, c).value for c in ("dt_um", "dt_lb_um", "dt_ub_um"))
    if not (np.isfinite(dt) and dt > 0) or (weber and not np.isfinite(std)):
        return
    scale = 1.0 / std if weber else 1.0
    color, words = f"C{k}", condition_words(r["standard_speed_mm_s"], r["comparison_speed_mm_s"])
    grid = np.linspace(0.0, top_um, 200)
    ax.plot(grid * scale, human_curve(grid, dt), "-" if same else "--", color=color,
            label=f"human, {words}" + ("" if same else " (Δ from the PSE)"))
    if np.isfinite(lb) and np.isfinite(ub):
        ax.fill_between(grid * scale, human_curve(grid, ub), human_curve(grid, lb), color=color, alpha=0.15, lw=0)
        ax.errorbar([dt * scale], [0.75], xerr=error_span([dt * scale], [lb * scale], [ub * scale]), fmt="v", ms=5,
                    color=color, capsize=3)
    if same and human.trials is not None:
        d, kk, n = folded_points(human.trials, float(r["standard_speed_mm_s"]), float(r["comparison_speed_mm_s"]))
        if d.size:
            lo, hi = _wilson(kk, n)
            ax.errorbar(d * scale, kk / n, yerr=[kk / n - lo, hi - kk / n], fmt="o", ms=3, color=color, capsize=2,
                        lw=0.8)


def _draw(axes, disc, human, shown: Shown) -> None:
    """P(correct) against Δ in µm (left) and as a fraction of the reference (right), the
    curves of fits that passed their verdict only."""
    top_um, top_w = _thresholds(disc, human, shown)
    for ax, weber in zip(axes, (False, True)):
        top = 2.5 * (top_w if weber else top_um)
        if disc is not None and shown.robot:
            _robot(ax, disc, 1.0 / disc.reference_um if weber else 1.0)
        if human.pooled is not None and shown.human:
            for k, (_, r) in enumerate(human.pooled.iterrows()):
                std = human.standard_um(r)
                _human(ax, human, k, r, weber, top * (std if weber and np.isfinite(std) else 1.0))
        ax.axhline(0.75, color="0.5", lw=0.7, ls=":")
        ax.set(xlim=(0.0, top), ylim=(0.45, 1.02), ylabel="P(correct), 2AFC",
               xlabel="height difference Δ / reference (Weber fraction)" if weber else "height difference Δ (µm)",
               title="As Weber fractions" if weber else "In µm")


def _human_data_figure(human, fitted: bool = True):
    """P("comparison higher") against the comparison height per condition, pooled over
    subjects (Wilson 95 % intervals), with the pooled fit when there is one (and
    ``fitted``: the fit passed its verdict)."""
    from scipy.stats import norm

    t = human.trials
    fig, ax = subplots(width_in=5.2, height_in=2.8)
    conds = t.groupby(["standard_speed_mm_s", "comparison_speed_mm_s"], sort=True)
    for k, ((vs, vc), g) in enumerate(conds):
        agg = g.groupby("comparison_um")[["n_comparison_higher", "n_trials"]].sum()
        k_, n = agg["n_comparison_higher"].to_numpy(float), agg["n_trials"].to_numpy(float)
        lo, hi = _wilson(k_, n)
        words = condition_words(vs, vc)
        ax.errorbar(agg.index, k_ / n, yerr=[k_ / n - lo, hi - k_ / n], fmt="o", ms=3, capsize=2, color=f"C{k}",
                    label=f"data, {words}")
        if human.pooled is not None and fitted:
            rows = human.pooled[(human.pooled["standard_speed_mm_s"].astype(float) == vs)
                                & (human.pooled["comparison_speed_mm_s"].astype(float) == vc)]
            for _, r in rows.iterrows():
                pse, dt = human.value(r, "pse_um").value, human.value(r, "dt_um").value
                if np.isfinite(pse) and np.isfinite(dt) and dt > 0:
                    x = np.linspace(agg.index.min() - 0.5, agg.index.max() + 0.5, 200)
                    ax.plot(x, norm.cdf(Z75 * (x - pse) / dt), "-", color=f"C{k}", lw=1,
                            label=f"fit: PSE {fmt(pse, 3)} µm, DT {fmt(dt, 3)} µm")
    ax.axhline(0.5, color="0.6", lw=0.6, ls=":")
    ax.set(xlabel="comparison height (µm)", ylabel="P(comparison judged higher)", ylim=(-0.02, 1.02),
           title="Human 2AFC data, all subjects pooled")
    ax.legend(fontsize=6, loc="upper left")
    lines = ("lines: the pooled cumulative normal through the PSE and DT (lapse not drawn)." if fitted else
             "the fit's curves are not drawn: it failed its verdict.")
    return make_figure("Human 2AFC data and the pooled psychometric functions", fig,
                       tuple(p for p in (human.trials_rel, human.thresholds_rel) if p),
                       "Dots: proportion of trials judging the comparison higher (Wilson 95 % intervals); " + lines)


def _pse_means(height_speed, standard_um, standard_speed) -> str:
    """What a PSE is, in one reading for every row: "height at 1 mm/s felt equal to 100 µm at 0.5 mm/s"."""
    if height_speed is None or standard_speed is None:
        return "–"
    return f"height at {fmt(height_speed)} mm/s felt equal to {fmt(standard_um, 3)} µm at {fmt(standard_speed)} mm/s"


#: the PSE column read the same way for robot and human (an outside review read them as opposite)
PSE_CAPTION = ("PSE: the height at the test or comparison speed felt equal to the reference or standard at its "
               "speed (column 'PSE is the'). Faster feels higher when the PSE at the faster speed lies below the "
               "reference (the robot's rows) or the PSE at the slower speed above the standard (the human's).")


def _table(disc, human, shown: Shown = Shown()) -> Table:
    rows, src, marks = [], [], []
    if disc is not None:
        pse = disc.pse_um.text(3, "µm") if disc.pse_um is not None else "–"
        means = (_pse_means(disc.pse_speeds[1], disc.reference_um, disc.pse_speeds[0])
                 if disc.pse_um is not None else "–")
        who = ("robot" + (" — EXTRAPOLATED (outside the trained plates)" if disc.extrapolated else "")
               + ("" if shown.robot else f" — {FAILED_FIT}"))
        rows.append((who, f"reference {fmt(disc.reference_um, 3)} µm", disc.threshold_um.text(3),
                     disc.weber.text(3), pse, means))
        marks.append("" if shown.robot else "failed")
        src.append(disc.part.path("discrimination.json"))
    if human.pooled is not None:
        for _, r in human.pooled.iterrows():
            std = human.standard_um(r)
            dt = [human.value(r, c).value for c in ("dt_um", "dt_lb_um", "dt_ub_um")]
            pse = [human.value(r, c).value for c in ("pse_um", "pse_lb_um", "pse_ub_um")]
            who = ("human" + (" (SYNTHETIC)" if human.label else "") + f" {r['subject']}"
                   + ("" if shown.human else f" — {FAILED_FIT}"))
            marks.append("" if shown.human else "failed")
            rows.append((who, f"{fmt(std)} µm, {condition_words(r['standard_speed_mm_s'], r['comparison_speed_mm_s'])}",
                         interval(*dt), interval(*(np.array(dt) / std)) if np.isfinite(std) else "–",
                         interval(*pse) + " µm",
                         _pse_means(float(r["comparison_speed_mm_s"]), std, float(r["standard_speed_mm_s"]))))
        src.append(human.thresholds_rel)
    return Table("Difference thresholds (75 % correct), Weber fractions and PSEs, 95 % intervals",
                 ("who", "reference or standard", "DT (µm)", "Weber DT / reference", "PSE", "PSE is the"),
                 tuple(rows), tuple(src),
                 caption=PSE_CAPTION + ("" if shown.robot and shown.human else
                                        f" Rows marked '{FAILED_FIT}' are not results."),
                 marks=tuple(marks) if any(marks) else ())


#: M3's pairs against the robot section's table (an outside review found two P(correct) for one pair)
MODEL_PAIRS = ("Model-based (M3): fresh touches simulated from the calibrated model, each posterior draw deciding "
               "by the larger peak z (one decoder for every touch), with the Monte Carlo and posterior error. "
               "The robot section's 'empirical' table counts pairs of this run's own scans instead (a few dozen a "
               "plate, so its interval is wide): the two estimate different things and need not agree.")


def compare_inputs(inv, spec) -> None:
    """Read the robot's discrimination, the human data and their fits' verdicts before the
    report's first figure (cached for the section)."""
    _shown(inv, robot_disc(inv), human_data(inv))


def compare_section(inv, spec) -> Section:
    """The two psychometric functions on one axis, in µm and as Weber fractions, and tables."""
    disc, human = robot_disc(inv), human_data(inv)
    shown = _shown(inv, disc, human)
    blocks = list(shown.notes)
    if human.label:
        blocks.append(Note(human.label, level="synthetic", sources=(human.trials_rel or human.thresholds_rel,)))
    if disc is not None and disc.notes:
        blocks += [Note(n, level="failed" if disc.extrapolated else "info",
                        sources=(disc.part.path("discrimination.json"),)) for n in disc.notes]
    if (disc is not None and shown.robot) or (human.pooled is not None and shown.human):
        fig, axes = subplots(2, width_in=3.5, height_in=3.1)
        _draw(axes, disc, human, shown)
        handles, labels = axes[0].get_legend_handles_labels()
        fig.legend(handles, labels, loc="outside lower center", ncol=2, fontsize=6, frameon=False)
        src = [p for p in ((disc.part.path("discrimination.json") if disc else ""),
                           (disc.curve_rel if disc is not None else ""), human.thresholds_rel, human.trials_rel) if p]
        caption = ("Robot: P(correct) that the reference + Δ gives the larger peak z, with its 95 % band. Human: "
                   "the pooled cumulative normal through the DT (lapse not drawn), band from the DT's interval; "
                   "dots: pooled data folded about the standard (Wilson 95 % intervals). Triangles: thresholds at "
                   "75 %, with their intervals.")
        if disc is not None and disc.curve is None:
            caption += (f" The robot's curve is not in this run (it needs {disc.part.path('threshold_curve.csv')}); "
                        "its threshold is marked.")
        blocks.append(make_figure("Robot and human psychometric functions on one axis", fig, tuple(dict.fromkeys(src)),
                                  caption))
    blocks.append(_table(disc, human, shown))
    if disc is not None and len(disc.pairs):
        pairs = "; ".join(f"{fmt(r[0])} vs {fmt(r[1])} mm: {interval(r[2], r[3], r[4], 4)}" for r in pairs_frame(disc))
        blocks.append(Note(f"Robot, model-based 2AFC P(correct) [95 %] of pairs of plates"
                           + ("" if shown.robot else f" ({FAILED_FIT})") + f": {pairs}. {MODEL_PAIRS}",
                           sources=(disc.part.path("discrimination.json"),)))
    # the human data last: a figure is never split, so the section's last page holds a whole figure, where the
    # text after it left the demo's last page of the section to the end of a paragraph (review s49, item 21)
    if human.trials is not None:
        blocks.append(_human_data_figure(human, fitted=shown.human))
    return Section(spec.key, spec.title, tuple(blocks))
