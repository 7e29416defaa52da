"""The first page: did this run reproduce the paper, and what did it find?

Claim by claim (:mod:`feeler.reports.claims`): the paper's statement and number, this
run's with its 95 % interval, the criterion and the mark; then every fit's verdict,
failed ones first; then what the run holds and what each missing part would need.
"""
from __future__ import annotations

from collections import Counter

from feeler.reports.model import Note, Section, Table, fmt

__all__ = ["front_section", "front_inputs", "fit_verdicts"]

_KIND_WORDS = {"robot": "simulated robot scans", "acquisition": "acquired robot scans",
               "calibration-data": "a sensor calibration campaign", "psychophysics": "human 2AFC trials",
               "thresholds": "psychometric thresholds", "tau-report": "a τ report", "classify": "a classification",
               "discriminate": "the robot's discrimination", "finger": "finger strain histories",
               "skin-figures": "skin figure tables", "ladder": "a skin ladder study",
               "benchmarks": "benchmark tables", "speed": "speed/accuracy tables measured by the demo"}


def front_inputs(inv) -> None:
    """Read what the first page's claims and verdicts use, before the report's first figure:
    the robot scans, the finger histories, the human data, the robot's discrimination, the
    τ report and every fit's verdict (the sections read most of them too, from the cache)."""
    from feeler.reports.claims import _robot
    from feeler.reports.claims_human import tau_report
    from feeler.reports.discdata import robot_disc
    from feeler.reports.fingerdata import finger_data
    from feeler.reports.humandata import human_data

    _robot(inv)
    finger_data(inv)
    human_data(inv)
    robot_disc(inv)
    tau_report(inv)
    fit_verdicts(inv)


def fit_verdicts(inv) -> list[tuple[bool, str, str, str, str]]:
    """(ok, fit, directory, backend and seconds, verdict text) per fit, failed first."""
    from feeler.reports.discover import FIT_TITLES
    from feeler.reports.readers import run_json

    rows = []
    for p in inv.of("fit"):
        v = run_json(inv, p.path("verdict.json"), ("ok",))
        ok = bool(v["ok"])
        problems = "; ".join(str(x) for x in v.get("problems", []))
        backend = ""
        if inv.has(p.path("posterior.nc")):
            from feeler.reports.readers import load_fit
            r = load_fit(inv.run_dir / p.rel, inv)
            backend = f"{r.backend}, {fmt(r.seconds, 3)} s"
        rows.append((ok, FIT_TITLES.get(p.model, "fit"), p.label, backend,
                     "passed" if ok else f"FAILED: {problems}"))
    return sorted(rows, key=lambda r: r[0])


def _holds(inv) -> str:
    if not inv.parts:
        return "Nothing this report recognises (no scans, fits, trials, strain histories or tables)."
    by_dir: dict[str, list[str]] = {}
    for p in inv.parts:
        by_dir.setdefault(p.label, []).append(_KIND_WORDS.get(p.kind, p.kind) if p.kind != "fit"
                                              else f"a fit ({p.model or 'model not recognised'})")
    return "; ".join(f"{d} {', '.join(dict.fromkeys(k))}" for d, k in by_dir.items()) + "."


def front_section(inv) -> Section:
    from feeler.reports.claims import MARKS, mark_class, paper_claims

    claims = paper_claims(inv)
    counts = Counter(c.mark for c in claims)
    order = [m for m in MARKS if m in counts] + [m for m in counts if m not in MARKS]
    summary = ", ".join(f"{counts[m]} {m}" for m in order)
    verdicts = fit_verdicts(inv)
    failed = sum(not ok for ok, *_ in verdicts)
    blocks = [Note(f"{len(claims)} claims checked: {summary}. Fits: {len(verdicts) - failed} passed"
                   + (f", {failed} FAILED (shown first)" if failed else "") + ".",
                   level="failed" if failed else "info")]
    rows = tuple((str(i), c.claim, c.paper, c.run, c.criterion, c.mark.upper()) for i, c in enumerate(claims, 1))
    sources = tuple(dict.fromkeys(s for c in claims for s in c.sources if s))
    blocks.append(Table("The paper's claims against this run", ("#", "claim (paper)", "paper", "this run [95 % interval]",
                                                                "criterion", "mark"), rows, sources,
                        marks=tuple(mark_class(c.mark) for c in claims)))
    if verdicts:
        blocks.append(Table("Verdict of every fit", ("fit", "directory", "backend", "verdict"),
                            tuple(r[1:] for r in verdicts), tuple(p.path("verdict.json") for p in inv.of("fit")),
                            marks=tuple("passed" if r[0] else "failed" for r in verdicts)))
    else:
        blocks.append(Note("No fits in this run."))
    blocks.append(Note("This run holds: " + _holds(inv)))
    if inv.unread:
        blocks.append(Note("Not reported (the report does not read them): "
                           + ", ".join(f"{rel} ({what})" for rel, what in inv.unread) + ".",
                           sources=tuple(rel for rel, _ in inv.unread)))
    if inv.missing:
        rows = tuple((m.title, m.needs) for m in inv.missing)
        blocks.append(Table("Not in this run, and what each would need", ("section", "would need"), rows, ()))
        if inv.missing_note:
            blocks.append(Note(inv.missing_note[0].upper() + inv.missing_note[1:] + "."))
    return Section("front", "Did it reproduce the paper, and what did it find?", tuple(blocks))
