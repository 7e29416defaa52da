"""Classification section: confusion matrix with confidence, the decoded heights with
their intervals, calibration curve, coverage.

Reads ``classification.csv`` as written by ``feeler classify --out``: one row per scan with
its labelled ``step_mm``, the decided ``plate_mm``, one probability column ``p_<plate>mm``
per training plate and the decoded height with its 90 % interval (other columns may
appear and are ignored). A calibration curve is drawn only when the top-class
probabilities spread over at least three of its ten bins; otherwise it would be one
point, and the section says why it is left out.
"""
from __future__ import annotations

import re

import numpy as np

from feeler.reports.model import Figure, Note, Section, Table, fmt, make_figure, subplots
from feeler.reports.readers import run_table

__all__ = ["classify_section", "classify_inputs", "plate_columns", "reliability", "MIN_BINS"]

MIN_BINS = 3             # a calibration curve needs this many occupied confidence bins
_P = re.compile(r"^p_(.+)mm$")


def plate_columns(columns) -> dict[str, float]:
    """``{"p_0.05mm": 0.05, ...}`` for every probability column."""
    found = {}
    for c in columns:
        m = _P.match(str(c))
        if m:
            try:
                found[str(c)] = float(m.group(1))
            except ValueError:
                continue
    return found


def reliability(conf, hit, n_bins: int = 10):
    """Per equal-width confidence bin: (mean confidence, accuracy, count); empty bins dropped."""
    conf, hit = np.asarray(conf, float), np.asarray(hit, bool)
    bins = np.minimum((conf * n_bins).astype(int), n_bins - 1)
    rows = [(conf[bins == b].mean(), hit[bins == b].mean(), int((bins == b).sum())) for b in np.unique(bins)]
    return np.array(rows, float).reshape(-1, 3)


def _classification(inv, part):
    """(classification.csv with its numeric columns, its probability columns {name: plate mm})."""
    from feeler.errors import DataFileError

    rel = part.path("classification.csv")
    cols = ("step_mm", "plate_mm", "lo90_mm", "hi90_mm")
    frame = run_table(inv, rel, cols, cols)
    pcols = plate_columns(frame.columns)
    if not pcols:
        raise DataFileError(inv.run_dir / rel, "no probability columns p_<plate>mm")
    run_table(inv, rel, tuple(pcols), tuple(pcols))            # every probability numeric
    return frame, pcols


def classify_inputs(inv, spec) -> None:
    """Read and check classification.csv before the report's first figure."""
    _classification(inv, spec.parts[0])


def classify_section(inv, spec) -> Section:
    """Confusion matrix (counts and mean confidence), calibration curve and summary table."""
    from feeler.calib.neuron.classify import expected_calibration_error
    from feeler.calib.neuron.live.table import claims_check, coverage_note, plate_column

    part = spec.parts[0]
    rel = part.path("classification.csv")
    frame, pcols = _classification(inv, part)
    src = (rel,)
    left_out = ""
    if "flagged" in frame.columns:      # outside the fit's envelope: left out, as `feeler classify` does
        flagged = frame["flagged"].astype(str).str.strip().str.lower().isin(("true", "1")).to_numpy()
        if flagged.all():
            return Section(spec.key, spec.title, (Note(
                f"All {len(frame)} classified scans are flagged as unlike the fit's training scans (their reasons "
                f"are in the flag column): no accuracy, confidence or coverage to report.", sources=src),))
        if flagged.any():
            left_out = (f" {int(flagged.sum())} of {len(frame)} scans, flagged as unlike the fit's training scans, "
                        f"are left out.")
        frame = frame[~flagged]
    plates = np.array(list(pcols.values()))
    prob = frame[list(pcols)].to_numpy(float)
    step, decided = frame["step_mm"].to_numpy(float), frame["plate_mm"].to_numpy(float)
    conf = prob.max(axis=1)
    labelled = np.isclose(step[:, None], plates[None]).any(axis=1)
    true_index = np.argmax(np.isclose(step[:, None], plates[None]), axis=1)
    hit = np.isclose(step, decided)
    inside = (step >= frame["lo90_mm"].to_numpy()) & (step <= frame["hi90_mm"].to_numpy())
    ece = expected_calibration_error(prob[labelled], true_index[labelled]) if labelled.any() else float("nan")
    rows = [("all", str(len(step)), fmt(hit.mean(), 3), fmt(conf.mean(), 3), fmt(inside.mean(), 3))]
    for s in np.unique(step):
        m = step == s
        rows.append((fmt(s), str(int(m.sum())), fmt(hit[m].mean(), 3), fmt(conf[m].mean(), 3), fmt(inside[m].mean(), 3)))
    table = Table("Accuracy, confidence and coverage per labelled step",
                  ("step_mm", "n scans", "accuracy", "mean top probability", "90 % interval coverage"),
                  tuple(rows), src, caption=f"Expected calibration error (10 bins): {fmt(ece, 3)}.{left_out}")
    blocks = [_confusion(step, decided, conf, plates, src), _heights(frame, step, src)]
    claims = claims_check(frame.drop(columns="flagged", errors="ignore")          # as `feeler classify` warns
                          .rename(columns={c: plate_column(v) for c, v in pcols.items()}), plates)
    if claims:
        blocks.insert(0, Note("Warning: " + " Warning: ".join(c[0].upper() + c[1:] + "." for c in claims),
                              sources=src))
    wide = coverage_note(frame.drop(columns="flagged", errors="ignore")
                         .rename(columns={c: plate_column(v) for c, v in pcols.items()}), plates)
    if wide:
        blocks.insert(len(claims) > 0, Note("Note: " + wide[0].upper() + wide[1:] + ".", sources=src))
    rel_curve = reliability(conf, hit)
    if len(rel_curve) >= MIN_BINS:
        blocks.append(_calibration(conf, hit, ece, src))
    else:
        blocks.append(Note(f"No calibration curve: the top-class probabilities of the {len(step)} scans fall in "
                           f"{len(rel_curve)} of 10 bins (mean {fmt(conf.mean(), 4)}, accuracy {fmt(hit.mean(), 3)}), "
                           "so the curve would be a single point. The 90 % interval coverage below is the "
                           "calibration check that informs.", sources=src))
    return Section(spec.key, spec.title, tuple(blocks) + (table,))


def _heights(frame, step, src) -> Figure:
    """Decoded height and its 90 % interval per scan, grouped by labelled step."""
    fig, ax = subplots(width_in=4.4, height_in=2.8)
    est = frame["height_mm"].to_numpy(float) if "height_mm" in frame else None
    lo, hi = frame["lo90_mm"].to_numpy(float), frame["hi90_mm"].to_numpy(float)
    mid = est if est is not None else (lo + hi) / 2
    order = np.lexsort((mid, step))
    x = np.arange(len(step))
    inside = (step[order] >= lo[order]) & (step[order] <= hi[order])
    for ok, color, label in ((True, "C0", "label inside the 90 % interval"), (False, "C3", "label outside")):
        m = inside == ok
        if m.any():                  # intervals as lines: an estimate may lie outside its interval
            ax.vlines(x[m], lo[order][m], hi[order][m], lw=0.6, color=color)
            ax.plot(x[m], mid[order][m], ".", ms=3, color=color, label=label)
    ax.plot(x, step[order], "k_", ms=4, label="labelled step")
    ax.set(xlabel="scan (sorted by labelled step, then estimate)", ylabel="step height (mm)",
           title="Decoded height with its 90 % interval")
    ax.legend(fontsize=6)
    return make_figure("Decoded heights of the held-out scans", fig, src,
                       "Each scan's continuous estimate and 90 % interval against its labelled step.")


def _confusion(step, decided, conf, plates, src) -> Figure:
    labels = np.unique(step)
    count = np.array([[np.sum((step == s) & np.isclose(decided, p)) for p in plates] for s in labels])
    n = max(len(plates), len(labels))
    # up to 6 plates: count and confidence per cell; more: the figure grows to the page's
    # width, and past 8 a cell holds its count only, past 12 nothing (the colour says it)
    side = min(6.2, max(3.0, 0.3 * n + 1.2))
    fig, ax = subplots(width_in=side + 0.6, height_in=side)
    ax.imshow(count, cmap="Blues")
    size = 7 if n <= 6 else 6 if n <= 8 else 5
    for i, s in enumerate(labels):
        for j, p in enumerate(plates):
            m = (step == s) & np.isclose(decided, p)
            if m.any() and n <= 12:
                text = f"{count[i, j]}\n{conf[m].mean():.2f}" if n <= 8 else f"{count[i, j]}"
                ax.text(j, i, text, ha="center", va="center", fontsize=size,
                        color="white" if count[i, j] > count.max() / 2 else "black")
    ax.set_xticks(range(len(plates)), [f"{p:g}" for p in plates], rotation=90 if n > 6 else 0)
    ax.set_yticks(range(len(labels)), [f"{s:g}" for s in labels])
    ax.set(xlabel="decided plate (mm)", ylabel="labelled step (mm)", title="Confusion matrix")
    what = ("number of scans and their mean top-class probability" if n <= 8 else
            "number of scans (the colour: more scans darker)" if n <= 12 else
            "coloured by its number of scans, darker for more")
    return make_figure("Confusion matrix with confidence" if n <= 8 else "Confusion matrix", fig, src,
                       f"Each cell: {what}.")


def _calibration(conf, hit, ece, src) -> Figure:
    rel = reliability(conf, hit)
    fig, ax = subplots(width_in=3.6, height_in=3.0)
    ax.plot([0, 1], [0, 1], "k--", lw=0.8, label="perfect calibration")
    ax.plot(rel[:, 0], rel[:, 1], "o-", label=f"classifier (ECE {ece:.3f})")
    # the counts in a row along the floor, under their bins: beside the points they crossed the right frame (the
    # hard demo's '38' at 0.98) or the lines, which near (1, 1) leave no room (an outside reader)
    for x, _, n in rel:
        right = x > 0.9
        ax.annotate(f"{int(n)}", (x, 0.0), fontsize=6, color="C0", textcoords="offset points", va="bottom",
                    ha="right" if right else "center", xytext=(3 if right else 0, 2))
    ax.set(xlim=(0, 1.02), ylim=(0, 1.02), xlabel="top-class probability",
           ylabel="fraction correct", title="Calibration curve")
    ax.legend(fontsize=7, loc="upper left")
    return make_figure("Calibration curve of the classifier", fig, src,
                       "Scans binned by top-class probability (bottom row: scans per bin).")
