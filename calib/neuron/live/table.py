"""The per-scan table of ``feeler classify`` and ``feeler decode``, and the unit check
both make before they answer.

Columns: ``scan_id``, ``step_mm`` (when labelled), ``plate_mm`` (most probable plate at the
scan's end), ``p_<plate>mm`` for every plate, ``height_mm``, ``lo90_mm``, ``hi90_mm``
(decoded step and 90 % interval at the scan's end), ``flagged`` and ``flag`` (why the scan
lies outside the fit's training envelope; empty when inside).
"""
from __future__ import annotations

import numpy as np

from feeler.errors import DataFileError

__all__ = ["plate_column", "unit_mistake", "copies_note", "labelled_summary", "claims_check", "coverage_note", "on_a_plate",
           "off_plate_note", "OFF_PLATE_MIN_SCANS", "OFF_PLATE_SHARE"]

# a labelled batch contradicts the fit when what it claims is this improbable (one-sided)…
CLAIM_P = 1e-3
# …and misses by this much: coverage below the 0.85 a 90 % interval should keep at worst,
# accuracy this far below what the probabilities promised (a small shortfall over
# thousands of scans is significant without mattering)
CLAIM_COVERAGE_MIN = 0.85
# coverage above this (the upper end of the band a 90 % interval should keep) and beyond
# chance is a note, not a warning: the intervals are conservative, not wrong
CLAIM_COVERAGE_MAX = 0.95
CLAIM_ACCURACY_SHORT = 0.05
CLAIM_MIN_SCANS = 20     # fewer usable scans than this: no judgement


#: a batch of at least this many scans with this share of them off every trained plate is
#: itself in doubt: fresh touches of the training plates lie within 4 sds (8200 of the hard
#: scenes and four-plates: largest 3.9), and U_y × 0.7 on four-plates put 30 of 96 scans
#: off-plate while 19 of the other 66 were read wrong at p >= 0.9 (an outside audit)
OFF_PLATE_MIN_SCANS = 20
OFF_PLATE_SHARE = 0.2


def off_plate_note(off: int, n: int, plate_sds: float, what: str = "probabilities") -> str | None:
    """A note when ``off`` of a batch of ``n`` scans read more than ``plate_sds`` sds from
    every trained plate and that is :data:`OFF_PLATE_SHARE` or more of a batch of
    :data:`OFF_PLATE_MIN_SCANS` or more (the batch itself, not only those scans, is then in
    doubt), else None; ``what`` names the other scans' answers."""
    if n < OFF_PLATE_MIN_SCANS or off < OFF_PLATE_SHARE * n:
        return None
    return (f"note: {off} of {n} scans read more than {plate_sds:g} sds from every trained plate: a batch on "
            f"another scale (a gain, a unit or a set-up unlike the training's) or of steps the fit was not "
            f"trained on, so the other scans' {what} may not hold either")


def copies_note(names, uy_mm) -> str | None:
    """A note when scans of a batch are copies of one another: the same U_y (mm) at every
    sample (``uy_mm``: one array per scan, ``names``: how each is named). No two touches
    of a real read-out agree to the last digit; a scan copied under new ids, or a read-out
    that did not change between touches, does (an outside audit: 96 copies of one scan
    were each classified at p = 0.999, without a word). None when no two are equal. A scan
    may come as its :func:`~.run.scan_key` (bytes), as ``decode`` keeps them."""
    from feeler.calib.neuron.live.run import scan_key

    first: dict[bytes, int] = {}
    copies = []
    for k, u in enumerate(uy_mm):
        key = u if isinstance(u, bytes) else scan_key(u)
        if key in first:
            copies.append((k, first[key]))
        else:
            first[key] = k
    if not copies:
        return None
    k, j = copies[0]
    return (f"note: {len(copies)} of {len(names)} scans repeat an earlier scan's U_y at every sample (e.g. "
            f"{names[k]} = {names[j]}): a scan copied under new ids, or a read-out that did not change between "
            f"touches? Each copy is classified as that one scan, so they are not {len(names)} independent readings")


def plate_column(step_mm: float) -> str:
    """``p_0.1mm``: the column of a plate's probability."""
    return f"p_{step_mm:g}mm"


def unit_mistake(path, scans, flags, fit_problems=()) -> None:
    """Raise a one-line DataFileError for the first scan whose flags name a unit mistake
    (``scans``: how each scan is named, ``scan_id 7`` or ``scan file touch8.csv``;
    ``flags``: one list of reasons per scan). ``fit_problems``: the fit's verdict; when it
    names a unit mistake of its own training scans (a failed fit used with
    ``--accept-failed``), the line says the fit may be the one off, not the new scans."""
    own = next((q for q in fit_problems if "probably in" in q), None)
    for name, reasons in zip(scans, flags):
        for r in reasons:
            if "probably in" in r:
                who = "" if r.startswith("these ") else f"{name}: "        # a batch's reason names no scan
                if own is not None:
                    raise DataFileError(path, f"{who}{r.split(':')[0]}: these scans and the fit's training scans "
                                              f"are on different scales, and the fit's own verdict names its "
                                              f"training scans' units ({own}); refit with them in mm")
                raise DataFileError(path, f"{who}{r}; the scan CSV takes t_s in s and uy_mm, x_mm in mm "
                                          "(README, 'Scan CSV format')")


def on_a_plate(step_mm, plates_mm) -> np.ndarray:
    """Which labels ``step_mm (ndarray[n])`` are the step of one of the fit's plates
    (ndarray[n] bool; NaN, no label, is on none)."""
    return np.isclose(np.asarray(step_mm, float)[:, None], np.asarray(plates_mm, float)[None, :]).any(axis=1)


def _usable_labels(table, plates_mm):
    """(the labelled, unflagged scans of ``table`` (a frame), how many labelled ones were
    flagged, which of the unflagged carry the step of a trained plate (ndarray[bool]));
    None without labels."""
    if "step_mm" not in table.columns:
        return None
    lab = table[np.isfinite(table["step_mm"].to_numpy(float))]
    if lab.empty:
        return None
    flagged = lab["flagged"].to_numpy(bool) if "flagged" in lab.columns else np.zeros(len(lab), bool)
    lab = lab[~flagged]
    return lab, int(flagged.sum()), on_a_plate(lab["step_mm"], plates_mm)


def _inside(lab) -> np.ndarray:
    """Which labels of the frame ``lab`` lie inside their 90 % interval (ndarray[bool])."""
    step = lab["step_mm"].to_numpy(float)
    return (step >= lab["lo90_mm"].to_numpy(float)) & (step <= lab["hi90_mm"].to_numpy(float))


def claims_check(table, plates_mm, *, decided: str = "plate_mm", promised: str | None = None) -> list[str]:
    """What a labelled batch says against the fit's claims, one line each; empty when
    nothing (or no labels, or fewer than 20 usable scans).

    Over the unflagged scans labelled with a trained plate:
    - coverage: k of n labels inside their 90 % interval, tested against Binomial(n, 0.9)
      (lower tail below :data:`CLAIM_P`) with k/n below :data:`CLAIM_COVERAGE_MIN`;
    - accuracy, over those with a plate in column ``decided`` (classify: the most probable
      plate; decode: the plate decided, NaN while undecided): the misses against those the
      probabilities allow, Σ (1 − p), with p the column ``promised`` (decode's
      ``p_decided``: a posterior at the time it is acted on is calibrated whenever that
      time is) or else the top plate probability: the upper tail of a Poisson of that
      mean, wider than the exact Poisson-binomial's (whose variance, Σ p(1 − p), is
      smaller), so the test errs towards silence; with the accuracy
      :data:`CLAIM_ACCURACY_SHORT` below the promised one.

    Such a batch differs from the training scans in a way the per-scan flags do not test
    (a wider pad, a harder press: a fit's four plates classified 2 mm-pad scans with 74 % of
    labels inside their 90 % intervals, every scan unflagged)."""
    from scipy.special import bdtr, pdtrc        # not scipy.stats: classify stays quick to import

    usable = _usable_labels(table, plates_mm)
    if usable is None:
        return []
    lab, _, known = usable
    lab = lab[known]
    out = []
    n = len(lab)
    step = lab["step_mm"].to_numpy(float)
    k = int(_inside(lab).sum())
    p_cover = float(bdtr(k, n, 0.9))
    if n >= CLAIM_MIN_SCANS and p_cover < CLAIM_P and k / n < CLAIM_COVERAGE_MIN:
        out.append(f"the fit's intervals do not hold for these scans: {k} of {n} labels inside their 90 % "
                   f"interval ({k / n * 100:.0f} %; p = {p_cover:.1g} for a 90 % interval)")
    plate = lab[decided].to_numpy(float)
    acted = np.isfinite(plate)
    p = (lab[promised].to_numpy(float) if promised else
         lab[[plate_column(v) for v in plates_mm]].to_numpy(float).max(axis=1))[acted]
    n = int(acted.sum())
    hits = int(np.isclose(plate[acted], step[acted]).sum())
    expected = float(p.sum())
    p_acc = float(pdtrc(n - hits - 1, n - expected)) if hits < n else 1.0
    if n >= CLAIM_MIN_SCANS and p_acc < CLAIM_P and hits / n < expected / n - CLAIM_ACCURACY_SHORT:
        said = (f"the decisions are over-confident for these scans: {hits} of {n} right where their "
                if promised else f"the plate probabilities are over-confident for these scans: {hits} of {n} "
                                 f"classified as their labelled plate where they ")
        out.append(f"{said}promised {expected:.0f} (p = {p_acc:.1g})")
    if out:
        out[-1] += ("; these scans differ from the training scans in a way the per-scan checks do not see "
                    "(another probe, press or set of plates?), or labels that are wrong: calibrate with "
                    "scans like them, or check the labels")
    return out


def coverage_note(table, plates_mm) -> str | None:
    """A line when a labelled batch is covered far more often than the 90 % claimed: over
    the unflagged scans labelled with a trained plate (at least :data:`CLAIM_MIN_SCANS`),
    k of n inside with the upper tail of Binomial(n, 0.9) below :data:`CLAIM_P` and k/n
    above :data:`CLAIM_COVERAGE_MAX`; None otherwise. The intervals then say less than
    they could: touches less noisy than the training ones (not flagged), or plates whose
    touches are flatter than Gaussian, which a Gaussian band over-covers (README, M2)."""
    from scipy.special import bdtrc

    usable = _usable_labels(table, plates_mm)
    if usable is None:
        return None
    lab = usable[0][usable[2]]
    n, k = len(lab), int(_inside(lab).sum())
    p_over = float(bdtrc(k - 1, n, 0.9)) if k > 0 else 1.0            # P(X >= k)
    if n < CLAIM_MIN_SCANS or p_over >= CLAIM_P or k / n <= CLAIM_COVERAGE_MAX:
        return None
    return (f"the fit's 90 % intervals are wider than they claim for these scans: {k} of {n} labels inside "
            f"({k / n * 100:.0f} %; p = {p_over:.1g} for a 90 % interval); touches less noisy than the training "
            f"scans, or plates whose touches are flatter than Gaussian, make them conservative (README, M2)")


def labelled_summary(table, plates_mm) -> str | None:
    """Accuracy and 90 % coverage over the labelled scans of ``table`` that are not
    flagged (outside the fit's training envelope, where its numbers mean nothing), with
    how many flagged ones were left out; None without labels."""
    usable = _usable_labels(table, plates_mm)
    if usable is None:
        return None
    lab, n_flagged, known = usable
    if lab.empty:
        return (f"{n_flagged} labelled scans, all flagged (outside the fit's training envelope: see the flags): "
                f"no accuracy to report")
    left_out = f"; {n_flagged} flagged scan(s) left out" if n_flagged else ""
    step = lab["step_mm"].to_numpy(float)
    hit = np.isclose(lab["plate_mm"].to_numpy(float), step)
    inside = _inside(lab)
    plates = np.asarray(plates_mm, float)
    extra = ""
    if (~known).any():
        extra = f" ({int((~known).sum())} labelled with a step the fit has no plate for"
        if np.isclose(step[~known, None] / 1000, plates[None, :], atol=1e-9).any(axis=1).all():
            extra += f": steps {step[~known].min():g}-{step[~known].max():g} against plates " \
                     f"{plates.min():g}-{plates.max():g} mm, so the labels are probably in um (expected mm)"
        elif plates.size > 1:
            off = np.min(np.abs(step[~known, None] - plates[None, :]), axis=1)
            if off.max() < 0.25 * np.min(np.diff(plates)):      # near a plate: a measured height, not a new step
                extra += (f": all within {off.max():.2g} mm of a trained plate, like measured heights; label each "
                          f"scan with its plate's step to count it")
        extra += ")"
    hits = (f"{hit[known].mean() * 100:.1f} % classified as their labelled plate" if known.all() else
            f"{hit[known].mean() * 100:.1f} % of the {int(known.sum())} labelled with a trained plate classified as it"
            if known.any() else "none labelled with a trained plate")
    return (f"{len(lab)} labelled scans: {hits}; {inside.mean() * 100:.1f} % of labels inside their 90 % interval"
            f"{extra}{left_out}")
