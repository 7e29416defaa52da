"""Classification section: confusion matrix with confidence, calibration curve, coverage.

Reads ``classify/classification.csv`` as written by ``feeler classify --out``: one row per
scan with its labelled ``step_mm``, the decided ``plate_mm``, one probability column
``p_<plate>mm`` per training plate and the decoded height with its 90 % interval.
"""
from __future__ import annotations

import re

import numpy as np

from feeler.reports.model import Figure, Section, Table, figure_uri, fmt, subplots
from feeler.reports.readers import read_table

__all__ = ["classify_section", "plate_columns", "reliability"]

CSV = "classify/classification.csv"
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


def classify_section(inv, spec) -> Section:
    """Confusion matrix (counts and mean confidence), calibration curve and summary table."""
    from feeler.calib.neuron.classify import expected_calibration_error
    from feeler.errors import DataFileError

    path = inv.run_dir / CSV
    frame = read_table(path, ("step_mm", "plate_mm", "lo90_mm", "hi90_mm"),
                       ("step_mm", "plate_mm", "lo90_mm", "hi90_mm"))
    pcols = plate_columns(frame.columns)
    if not pcols:
        raise DataFileError(path, "no probability columns p_<plate>mm")
    read_table(path, tuple(pcols), tuple(pcols))            # every probability numeric
    plates = np.array(list(pcols.values()))
    prob = frame[list(pcols)].to_numpy(float)
    step, decided = frame["step_mm"].to_numpy(float), frame["plate_mm"].to_numpy(float)
    conf = prob.max(axis=1)
    labelled = np.isclose(step[:, None], plates[None]).any(axis=1)
    true_index = np.argmax(np.isclose(step[:, None], plates[None]), axis=1)
    hit = np.isclose(step, decided)
    inside = (step >= frame["lo90_mm"].to_numpy()) & (step <= frame["hi90_mm"].to_numpy())
    ece = expected_calibration_error(prob[labelled], true_index[labelled]) if labelled.any() else float("nan")
    src = (CSV,)
    rows = [("all", str(len(step)), fmt(hit.mean(), 3), fmt(conf.mean(), 3), fmt(inside.mean(), 3))]
    for s in np.unique(step):
        m = step == s
        rows.append((fmt(s), str(int(m.sum())), fmt(hit[m].mean(), 3), fmt(conf[m].mean(), 3), fmt(inside[m].mean(), 3)))
    table = Table("Accuracy, confidence and coverage per labelled step",
                  ("step_mm", "n scans", "accuracy", "mean top probability", "90 % interval coverage"),
                  tuple(rows), src, caption=f"Expected calibration error (10 bins): {fmt(ece, 3)}.")
    return Section(spec.key, spec.title, (_confusion(step, decided, conf, plates, src),
                                          _calibration(conf, hit, ece, src), table))


def _confusion(step, decided, conf, plates, src) -> Figure:
    labels = np.unique(step)
    count = np.array([[np.sum((step == s) & np.isclose(decided, p)) for p in plates] for s in labels])
    fig, ax = subplots(width_in=4.6, height_in=3.8)
    ax.imshow(count, cmap="Blues")
    for i, s in enumerate(labels):
        for j, p in enumerate(plates):
            m = (step == s) & np.isclose(decided, p)
            if m.any():
                ax.text(j, i, f"{count[i, j]}\n{conf[m].mean():.2f}", ha="center", va="center", fontsize=7,
                        color="white" if count[i, j] > count.max() / 2 else "black")
    ax.set_xticks(range(len(plates)), [f"{p:g}" for p in plates])
    ax.set_yticks(range(len(labels)), [f"{s:g}" for s in labels])
    ax.set(xlabel="decided plate (mm)", ylabel="labelled step (mm)", title="Confusion matrix")
    return Figure("Confusion matrix with confidence", figure_uri(fig), src,
                  caption="Each cell: number of scans and their mean top-class probability.")


def _calibration(conf, hit, ece, src) -> Figure:
    rel = reliability(conf, hit)
    fig, ax = subplots(width_in=4.2, height_in=3.8)
    ax.plot([0, 1], [0, 1], "k--", lw=0.8, label="perfect calibration")
    ax.plot(rel[:, 0], rel[:, 1], "o-", label=f"classifier (ECE {ece:.3f})")
    for x, y, n in rel:
        ax.annotate(f"{int(n)}", (x, y), fontsize=6, textcoords="offset points", xytext=(3, -8))
    ax.set(xlim=(0, 1.02), ylim=(0, 1.02), xlabel="top-class probability",
           ylabel="fraction correct", title="Calibration curve")
    ax.legend(fontsize=7, loc="upper left")
    return Figure("Calibration curve of the classifier", figure_uri(fig), src,
                  caption="Scans binned by their top-class probability (numbers: scans per bin).")
