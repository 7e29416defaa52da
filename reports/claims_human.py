"""Claims about the human data and the robot against the human (see :mod:`feeler.reports.claims`).

Human numbers come from the pooled (``all``) rows of ``thresholds.csv``; when the trials
say they are synthetic, every row says so: the mark then checks the method on data
generated with the effect built in, not the paper, and a mark that would read "reproduced"
reads "synthetic: self-consistent". A robot threshold that the discrimination file says
is extrapolated (outside the trained plates) is marked "extrapolated".
"""
from __future__ import annotations

import math

import numpy as np

from feeler.reports.claims import Claim, absent
from feeler.reports.model import fmt, interval

__all__ = ["claim_faster_felt_higher", "claim_tau", "tau_report", "read_tau_report", "claim_threshold", "claim_weber", "human_reference_rows"]


def _verdict_ok(inv, part) -> bool | None:
    """The verdict of the fit in ``part``'s directory (None when there is none)."""
    from feeler.reports.readers import verdict_ok

    return verdict_ok(inv, part)


def _synthetic(human) -> str:
    return " — SYNTHETIC human data" if human.label else ""


def _self_consistent(mark: str, synthetic: bool) -> str:
    """On synthetic data a check that passes shows the method recovers what was built in."""
    return "synthetic: self-consistent" if synthetic and mark == "reproduced" else mark


#: the run text's tail when the robot's threshold rests on heights outside the trained plates
EXTRAPOLATED = " — EXTRAPOLATED: outside the plates the fit was trained on (see the discrimination notes)"


def human_reference_rows(human):
    """Pooled rows of the same-speed conditions (the human's own difference threshold),
    slowest first: list of (row, standard_um)."""
    if human.pooled is None:
        return []
    rows = [r for _, r in human.pooled.iterrows() if float(r["standard_speed_mm_s"]) == float(r["comparison_speed_mm_s"])]
    rows.sort(key=lambda r: float(r["standard_speed_mm_s"]))
    return [(r, human.standard_um(r)) for r in rows]


def claim_faster_felt_higher(inv) -> Claim:
    from feeler.reports.humandata import human_data

    key = "felt-higher"
    claim = "Humans feel a moving step higher at 40 than at 20 mm/s (§1, Fig. 6 symbols)"
    paper, crit = "PSE above the standard", "the PSE's 95 % interval above the standard height"
    human = human_data(inv)
    rows = [] if human.pooled is None else [r for _, r in human.pooled.iterrows()
                                            if float(r["standard_speed_mm_s"]) > float(r["comparison_speed_mm_s"])]
    if not rows:
        return absent(key, claim, paper, crit, "a psychometric fit with a faster standard (thresholds.csv)")
    r = rows[0]
    std = human.standard_um(r)
    pse, lo, hi = (human.value(r, c).value for c in ("pse_um", "pse_lb_um", "pse_ub_um"))
    mark = ("reproduced" if lo > std else "not reproduced" if hi < std else "inconclusive") if np.isfinite(std) \
        else "inconclusive"
    if _verdict_ok(inv, human.m4) is False:
        mark = "inconclusive"
    mark = _self_consistent(mark, bool(human.label))
    run = (f"PSE of {fmt(std)} µm at {float(r['standard_speed_mm_s']):g} mm/s against "
           f"{float(r['comparison_speed_mm_s']):g} mm/s: {interval(pse, lo, hi)} µm{_synthetic(human)}")
    return Claim(key, claim, paper, run, crit, mark, (human.thresholds_rel,))


def tau_report(inv) -> tuple:
    """(the run's τ report part, its tau_report.json), or (None, None)."""
    from feeler.reports.readers import run_json

    part = inv.first("tau-report", prefer="finger-route")
    return (None, None) if part is None else (part, read_tau_report(inv, part.path("tau_report.json")))


def read_tau_report(inv, rel: str) -> dict:
    """The run's ``rel`` (a tau_report.json, as `feeler fit finger-route` writes it), its
    fields checked: ``tau_median_s`` a number > 0; ``p_tau_le_300ms`` (if there) 0-1;
    ``tau_eti95_s`` (if there) two numbers. Else a one-line DataFileError naming the field
    (a hand-edited "abc" gave a ValueError traceback)."""
    from feeler.errors import DataFileError
    from feeler.reports.readers import run_json

    rep = run_json(inv, rel, ("tau_median_s",))

    def number(value) -> bool:
        return isinstance(value, (int, float)) and not isinstance(value, bool)

    def bad(key: str, allowed: str) -> DataFileError:
        return DataFileError(inv.run_dir / rel, f"{key} = {rep[key]!r:.40} must be {allowed}")

    if not number(rep["tau_median_s"]) or not rep["tau_median_s"] > 0:
        raise bad("tau_median_s", "> 0 (s)")
    p = rep.get("p_tau_le_300ms")
    if p is not None and not (number(p) and 0 <= p <= 1):
        raise bad("p_tau_le_300ms", "a probability, 0-1")
    eti = rep.get("tau_eti95_s")
    if eti is not None and not (isinstance(eti, list) and len(eti) == 2 and all(number(v) for v in eti)):
        raise bad("tau_eti95_s", "two numbers (s), the 95 % interval")
    return rep


def claim_tau(inv) -> Claim:
    key = "tau"
    claim = "τ ≤ 300 ms fits the human data (§4.2, Fig. 6)"
    paper, crit = "τ ≤ 300 ms", "P(τ ≤ 300 ms | data) ≥ 0.95 and the fit passed its diagnostics"
    part, rep = tau_report(inv)
    if part is None:
        return absent(key, claim, paper, crit, "the finger-route fit (tau_report.json)")
    p = float(rep.get("p_tau_le_300ms", math.nan))
    eti = list(rep.get("tau_eti95_s", [math.nan, math.nan]))[:2] + [math.nan, math.nan]
    ok = _verdict_ok(inv, part)
    mark = "reproduced" if p >= 0.95 else "not reproduced" if p <= 0.05 else "inconclusive"
    if ok is False:
        mark = "inconclusive"
    mark = _self_consistent(mark, bool(rep.get("synthetic_data")))
    synthetic = " — SYNTHETIC human data" if rep.get("synthetic_data") else ""
    failed = " — the fit FAILED its diagnostics" if ok is False else ""
    run = (f"τ {interval(float(rep['tau_median_s']) * 1e3, eti[0] * 1e3, eti[1] * 1e3)} ms; "
           f"P(τ ≤ 300 ms | data) = {fmt(p, 3)} (skin {str(rep.get('skin_level', '')).upper()}){synthetic}{failed}")
    return Claim(key, claim, paper, run, crit, mark, (part.path("tau_report.json"),))


def claim_threshold(inv) -> Claim:
    from feeler.reports.discdata import robot_disc

    key = "robot-threshold"
    claim = "The robot with the model distinguishes the plates' steps (§5.2, Fig. 9)"
    paper, crit = "0.05 vs 0.1 mm 'easy'", "difference threshold at 0.1 mm: its interval below half the reference"
    disc = robot_disc(inv)
    if disc is None:
        return absent(key, claim, paper, crit, "the robot's discrimination (discrimination.json)")
    th, half = disc.threshold_um, disc.reference_um / 2
    if th.bound == ">":
        mark = "not reproduced" if th.value >= half else "inconclusive"
    else:
        mark = "reproduced" if th.hi < half else "not reproduced" if th.lo >= half else "inconclusive"
    m2 = inv.first("fit", "m2", prefer="m2")
    if _verdict_ok(inv, m2) is False:
        mark = "inconclusive"
    elif disc.extrapolated:
        mark = "extrapolated"
    run = (f"{th.text(3, 'µm')} at {fmt(disc.reference_um, 3)} µm (half the reference: {fmt(half, 3)} µm); "
           f"Weber fraction {disc.weber.text(3)}" + (EXTRAPOLATED if disc.extrapolated else ""))
    return Claim(key, claim, paper, run, crit, mark, (disc.part.path("discrimination.json"),))


def claim_weber(inv) -> Claim:
    from feeler.reports.discdata import robot_disc
    from feeler.reports.humandata import human_data

    key = "weber"
    claim = "The robot's difference threshold against the human's, absolute and relative to each standard"
    paper = ("no number in Ohka et al.; human DT 0.95–2.0 µm (absolute) for 6.3–25 µm ridges, Miyaoka et al. "
             "1999 (DESIGN §8)")
    crit = ("finding: which is finer relative to its standard (Weber fraction DT / standard), when the 95 % "
            "intervals do not overlap; the absolute thresholds beside it")
    disc, human = robot_disc(inv), human_data(inv)
    rows = human_reference_rows(human)
    if disc is None or not rows:
        needs = " and ".join(n for n, ok in (("the robot's discrimination", disc is not None),
                                             ("a human psychometric fit", bool(rows))) if not ok)
        return absent(key, claim, paper, crit, needs)
    r, std = rows[0]
    dt = [human.value(r, c).value for c in ("dt_um", "dt_lb_um", "dt_ub_um")]
    hw = [v / std for v in dt]
    rw = disc.weber
    if rw.bound == ">" and rw.value > hw[2]:
        word = "relative to its standard the robot is coarser"
    elif not rw.bound and rw.hi < hw[1]:
        word = "relative to its standard the robot is finer"
    elif not rw.bound and rw.lo > hw[2]:
        word = "relative to its standard the robot is coarser"
    else:
        word = "relative to the standards no difference resolved"
    th = disc.threshold_um
    if np.isfinite(th.value) and dt[0] > 0:
        ratio = th.value / dt[0]
        word += (f"; in absolute terms its DT is {fmt(ratio, 2)}× the human's" if ratio >= 1 else
                 f"; in absolute terms its DT is {fmt(1 / ratio, 2)}× finer than the human's")
        word += f" (standards {fmt(disc.reference_um, 3)} and {fmt(std)} µm)"
    fits = (("the robot's M2 fit", inv.first("fit", "m2", prefer="m2")), ("the human's M4 fit", human.m4))
    failed = [who for who, part in fits if _verdict_ok(inv, part) is False]
    if failed:
        word = f"not compared: {' and '.join(failed)} FAILED its verdict"
    mark = "inconclusive" if failed else "extrapolated" if disc.extrapolated else "finding"
    run = (f"robot DT {th.text(3, 'µm')} at standard {fmt(disc.reference_um, 3)} µm, Weber {rw.text(3)}; "
           f"human DT {interval(*dt)} µm at standard {fmt(std)} µm ({float(r['standard_speed_mm_s']):g} mm/s), "
           f"Weber {interval(*hw)}{_synthetic(human)}: {word}"
           + (EXTRAPOLATED if disc.extrapolated and not failed else ""))
    return Claim(key, claim, paper, run, crit, mark, (disc.part.path("discrimination.json"), human.thresholds_rel))
