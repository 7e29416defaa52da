"""Robot against human: psychometric curves side by side, thresholds, PSEs and Weber
fractions; and the paper's Fig. 6 (accepted against presented step height, human points).

Robot numbers come from ``discriminate/discrimination.json`` (``feeler discriminate``),
human numbers from ``psychophysics/trials.csv`` and ``m4/thresholds.csv`` (``feeler fit
psychophysics``); the model line of Fig. 6 is the finger route at the τ of
``finger-route/tau_report.json``. Data whose files say they are synthetic are labelled so.
"""
from __future__ import annotations

import numpy as np

from feeler.reports.model import Figure, Note, Section, Table, figure_uri, fmt, subplots
from feeler.reports.readers import read_json, read_table

__all__ = ["psychometric_section", "fig6_section", "Z75"]

DISC, TRIALS, THRESH, TAU = ("discriminate/discrimination.json", "psychophysics/trials.csv",
                             "m4/thresholds.csv", "finger-route/tau_report.json")
Z75 = 0.6744897501960817            # Φ⁻¹(0.75): DT = σ·Z75 for a cumulative normal
_THRESH_COLS = ("subject", "standard_speed_mm_s", "comparison_speed_mm_s", "pse_um", "pse_lb_um",
                "pse_ub_um", "dt_um", "dt_lb_um", "dt_ub_um")


def _interval(mean, lo, hi, digits=3) -> str:
    return f"{fmt(mean, digits)} [{fmt(lo, digits)}, {fmt(hi, digits)}]"


def _human(inv):
    """(trials or None, pooled 'all' threshold rows or None, synthetic note)."""
    from feeler.psydata import read_trials, synthetic_note

    trials = read_trials(inv.run_dir / TRIALS) if inv.has(TRIALS) else None
    pooled = None
    if inv.has(THRESH):
        table = read_table(inv.run_dir / THRESH, _THRESH_COLS, _THRESH_COLS[1:])
        pooled = table[table["subject"].astype(str) == "all"]
        pooled = pooled if len(pooled) else table
    note = synthetic_note(trials) if trials is not None else ""
    if not note and pooled is not None and any("synthetic" in c.lower() for c in pooled.attrs["comments"]):
        note = "\n".join(pooled.attrs["comments"])
    return trials, pooled, note


def _synthetic_label(what: str, note: str) -> list:
    """[the SYNTHETIC note of the trial file] when its comments say so, else []."""
    text = f"{what}: SYNTHETIC — " + note.replace("\n", " ")
    return [Note(text, level="synthetic", sources=(TRIALS,))] if note else []


def _standard_um(trials, speed) -> float:
    rows = trials[trials["standard_speed_mm_s"] == speed]["standard_um"].unique()
    return float(rows[0]) if len(rows) == 1 else float("nan")


def psychometric_section(inv, spec) -> Section:
    """Robot 2AFC curve (left) and human psychometric data and fits (right), with tables."""
    trials, pooled, note = _human(inv)
    disc = read_json(inv.run_dir / DISC, ("pairs", "threshold_mm", "weber", "pse")) if inv.has(DISC) else None
    blocks = _synthetic_label("Human data", note)
    fig, (left, right) = subplots(2, width_in=4.4, height_in=3.6)
    if disc is not None:
        _robot_panel(left, disc)
        blocks.append(_robot_table(disc))
    else:
        left.set_axis_off()
        left.text(0.5, 0.5, f"no robot data ({DISC} missing)", ha="center", fontsize=8)
    if trials is not None or pooled is not None:
        _human_panel(right, trials, pooled, synthetic=bool(note))
    if pooled is not None:
        blocks.append(_human_table(pooled, trials))
    sources = tuple(f for f in (DISC, TRIALS, THRESH) if inv.has(f))
    blocks.insert(0, Figure("Robot (left) and human (right) discrimination", figure_uri(fig), sources,
                            caption="Robot: 2AFC proportion correct with 95 % intervals. Human: pooled "
                                    "proportion 'comparison higher' and the fitted cumulative normal "
                                    "through the pooled PSE and DT (lapse not drawn)."))
    return Section(spec.key, spec.title, tuple(blocks))


def _robot_panel(ax, disc) -> None:
    pairs = disc["pairs"]
    diff = np.array([p["high_mm"] - p["low_mm"] for p in pairs])
    pc = np.array([p["pc"] for p in pairs])
    err = np.abs(np.array([[p["pc"] - p["lo95"], p["hi95"] - p["pc"]] for p in pairs]).T)
    ax.errorbar(diff, pc, yerr=err, fmt="o", capsize=3, label="pairs of heights")
    ax.axhline(0.75, color="grey", lw=0.8, ls="--")
    th = disc["threshold_mm"]
    ax.axvspan(th["lo95"], th["hi95"], color="C1", alpha=0.25, label=f"threshold {th['mean'] * 1e3:.3g} µm")
    positive = np.concatenate([diff[diff > 0], [v for v in (th["lo95"], th["mean"]) if v > 0]])
    if positive.size:                         # steps span decades: log axis over all of them
        ax.set(xscale="log", xlim=(positive.min() / 2, positive.max() * 2))
    ax.set(xlabel="height difference (mm)", ylabel="proportion correct (2AFC)",
           ylim=(0.4, 1.02), title=f"Robot (reference {disc.get('reference_mm', float('nan')):g} mm)")
    ax.legend(fontsize=7, loc="lower right")


def _human_panel(ax, trials, pooled, *, synthetic: bool) -> None:
    from scipy.stats import norm

    tag = " (SYNTHETIC)" if synthetic else ""
    speeds = sorted(set(trials["standard_speed_mm_s"]) if trials is not None else set(pooled["standard_speed_mm_s"]))
    for k, v in enumerate(speeds):
        if trials is not None:
            sel = trials[trials["standard_speed_mm_s"] == v].groupby("comparison_um")[["n_comparison_higher", "n_trials"]].sum()
            ax.plot(sel.index, sel["n_comparison_higher"] / sel["n_trials"], "o", color=f"C{k}",
                    label=f"standard at {v:g} mm/s")
        if pooled is not None:
            row = pooled[pooled["standard_speed_mm_s"] == v]
            if len(row):
                pse, dt = float(row["pse_um"].iloc[0]), float(row["dt_um"].iloc[0])
                x = np.linspace(pse - 4 * dt, pse + 4 * dt, 200)
                ax.plot(x, norm.cdf((x - pse) / (dt / Z75)), color=f"C{k}", lw=1,
                        label=f"fit (PSE {pse:.3g} µm, DT {dt:.3g} µm)")
                ax.axvline(pse, color=f"C{k}", lw=0.6, ls=":")
    ax.set(xlabel="comparison height (µm)", ylabel="P(comparison judged higher)", ylim=(-0.02, 1.02),
           title="Human" + tag)
    ax.legend(fontsize=7, loc="upper left")


def _robot_table(disc) -> Table:
    th, wb, pse = disc["threshold_mm"], disc["weber"], disc["pse"]
    rows = [("difference threshold at 75 % (mm)", _interval(th["mean"], th["lo95"], th["hi95"])),
            ("Weber fraction", _interval(wb["mean"], wb["lo95"], wb["hi95"])),
            (f"PSE of {fmt(disc.get('reference_mm'))} mm at {fmt(pse.get('speed_ref_mm_s'))} mm/s when "
             f"scanned at {fmt(pse.get('speed_test_mm_s'))} mm/s (mm)", _interval(pse["mean_mm"], pse["lo95"], pse["hi95"]))]
    rows += [(f"pc {fmt(p['low_mm'])} vs {fmt(p['high_mm'])} mm", _interval(p["pc"], p["lo95"], p["hi95"]))
             for p in disc["pairs"]]
    return Table("Robot: threshold, Weber fraction and PSE (95 % intervals)", ("quantity", "value"),
                 tuple(rows), (DISC,))


def _human_table(pooled, trials) -> Table:
    rows = []
    for _, r in pooled.iterrows():
        std = _standard_um(trials, r["standard_speed_mm_s"]) if trials is not None else float("nan")
        weber = _interval(r["dt_um"] / std, r["dt_lb_um"] / std, r["dt_ub_um"] / std) if np.isfinite(std) else "–"
        rows.append((str(r["subject"]), fmt(r["standard_speed_mm_s"]), fmt(r["comparison_speed_mm_s"]),
                     _interval(r["pse_um"], r["pse_lb_um"], r["pse_ub_um"]),
                     _interval(r["dt_um"], r["dt_lb_um"], r["dt_ub_um"]), weber))
    return Table("Human: PSE, difference threshold and Weber fraction (95 % intervals)",
                 ("subject", "standard mm/s", "comparison mm/s", "PSE (µm)", "DT (µm)", "Weber DT/standard"),
                 tuple(rows), (THRESH, TRIALS) if trials is not None else (THRESH,))


def fig6_section(inv, spec) -> Section:
    """Accepted height of the finger route at the fitted τ against presented height, with the
    human PSEs (pooled, 95 % intervals) as points."""
    from feeler.calib.psychometric.finger_route import accepted_heights
    from feeler.errors import DataFileError

    rep = read_json(inv.run_dir / TAU, ("tau_median_s",))
    tau_s = float(rep["tau_median_s"])
    if not tau_s > 0:
        raise DataFileError(inv.run_dir / TAU, f"tau_median_s = {tau_s!r} must be > 0")
    trials, pooled, note = _human(inv)
    speeds = sorted(set(pooled["standard_speed_mm_s"]))
    heights = np.linspace(5.0, 15.0, 5)
    stimuli = [(float(h), float(v)) for v in speeds for h in heights]
    level = str(rep.get("skin_level") or "l0")
    s_hat, _ = accepted_heights(stimuli, np.array([tau_s]), level=level)
    fig, ax = subplots(width_in=5.0, height_in=4.0)
    tag = " (SYNTHETIC)" if note else ""
    for k, v in enumerate(speeds):
        ax.plot(heights, s_hat[0, k * len(heights):(k + 1) * len(heights)], "-", color=f"C{k}",
                label=f"finger route, {v:g} mm/s")
        row = pooled[pooled["standard_speed_mm_s"] == v]
        std = _standard_um(trials, v) if trials is not None else float("nan")
        if len(row) and np.isfinite(std):
            pse, lo, hi = (float(row[c].iloc[0]) for c in ("pse_um", "pse_lb_um", "pse_ub_um"))
            ax.errorbar([std], [pse], yerr=[[pse - lo], [hi - pse]], fmt="s", color=f"C{k}", capsize=3,
                        label=f"human PSE{tag}, {v:g} mm/s")
    ax.plot(heights, heights, "k:", lw=0.7, label="accepted = presented")
    ax.set(xlabel="presented step height (µm)", ylabel="accepted step height (µm)",
           title=f"Fig. 6 at τ = {tau_s * 1e3:.0f} ms (skin {level})")
    ax.legend(fontsize=7)
    blocks = _synthetic_label("Human points", note)
    blocks.append(Figure("Accepted against presented step height", figure_uri(fig), (TAU, THRESH, TRIALS),
                         caption="Line: κ(τ)·peak z of the finger chain at the posterior median τ; "
                                 "points: pooled human PSEs of the standard."))
    blocks.append(Note(f"τ posterior median {fmt(tau_s * 1e3, 3)} ms, 95 % interval "
                       f"{' – '.join(fmt(x * 1e3, 3) for x in rep.get('tau_eti95_s', []))} ms; "
                       f"P(τ ≤ 300 ms | data) = {fmt(rep.get('p_tau_le_300ms'), 3)}. Paper: {rep.get('paper', '')}",
                       sources=(TAU,)))
    return Section(spec.key, spec.title, tuple(blocks))
