"""The speed/accuracy section: every trade the run measured, cost against error.

Tables come from two places, and each says which: ``make bench`` (``benchmarks/<module>.csv``
and ``ratios.csv``, copied by the demo; measured on the machine that ran the benchmarks)
or the demo itself (``speed/`` with ``speed.json``: small versions measured while the demo
ran, when no bench tables exist). A table with a time column and an error (or accuracy)
column is drawn as a trade plot, one point per option; any other table is listed. The
live decoder's decision-latency/accuracy trade has its place here: it is drawn from a
``decoder.csv`` as soon as one exists.
"""
from __future__ import annotations

import re

import numpy as np

from feeler.reports.model import Note, Section, Table, fmt, log_axis, make_figure, subplots, table_from_frame
from feeler.reports.readers import run_json, run_table

__all__ = ["speed_section", "speed_inputs", "trade_columns", "table_columns", "failed_rows", "TIME_COLS", "ERROR_COLS",
           "ACCURACY_COLS", "times"]

TIME_COLS = ("latency_s", "decision_latency_s", "seconds_per_slide", "seconds", "fit_s", "median_s", "min_s")
ERROR_COLS = ("error_ref_sd", "error_sd", "error", "rate_error", "max_abs_mean_err_sd", "max_error")
ACCURACY_COLS = ("accuracy", "pc", "proportion_correct")
_TITLES = {"m1": "M1 backends", "fidelity": "Sensor fidelity (M1 on each level)", "backends": "Calibration backends",
           "decoder": "Live decoder: decision latency against accuracy", "skin": "Skin ladder (speed only)"}
_AXIS = {"error_ref_sd": "error (reference posterior sds)", "max_abs_mean_err_sd": "largest |mean error| (reference sds)",
         "error_sd": "error against the truth (posterior sds)", "rate_error": "peak strain-rate error (relative)",
         "seconds": "seconds", "fit_s": "seconds to fit", "median_s": "seconds (median of rounds)",
         "min_s": "seconds (best round)",
         "latency_s": "decision latency (s)", "accuracy": "accuracy"}


#: legend entries a column beside a trade plot holds (fontsize 6 on its 2.3 in): more
#: options take more columns (20 random scenes in one column lost the last four below the edge)
LEGEND_ROWS = 14


def trade_columns(frame) -> tuple[str | None, str | None]:
    """(time column, error or accuracy column) of a table, None where absent."""
    cols = set(frame.columns)
    x = next((c for c in TIME_COLS if c in cols), None)
    y = next((c for c in ERROR_COLS + ACCURACY_COLS if c in cols), None)
    return x, y


def _option(frame) -> list[str]:
    if "option" in frame:
        return [str(v) for v in frame["option"]]
    if "benchmark" in frame:
        return [re.sub(r"-kw\d+$", "", m.group(1)) if (m := re.search(r"\[(.+)\]", str(b))) else str(b)
                for b in frame["benchmark"]]
    return [str(i) for i in range(len(frame))]


def _shared_label(labels: list[str]) -> str:
    """One legend entry for options at one point: their common first word said once
    ("threshold 0.5, 0.7, 0.9"), two values a line."""
    if len(labels) == 1:
        return labels[0]
    heads = {lab.split(" ", 1)[0] for lab in labels}
    if len(heads) == 1 and all(" " in lab for lab in labels):
        head, rest = heads.pop() + " ", [lab.split(" ", 1)[1] for lab in labels]
    else:
        head, rest = "", labels
    lines = [", ".join(rest[i:i + 2]) for i in range(0, len(rest), 2)]
    return head + ",\n".join(lines)


#: a table's column holding each row's fit verdict (True: passed)
OK_COLS = ("ok", "verdict_ok")
#: what a failed fit's point and row are labelled with (README: "a failed fit's numbers are
#: marked wherever they appear")
FAILED_MARK = "failed its verdict"


def failed_rows(frame) -> np.ndarray:
    """One bool a row: the fit of that row failed its verdict (its ``ok`` column is false)."""
    col = next((c for c in OK_COLS if c in frame.columns), None)
    if col is None:
        return np.zeros(len(frame), bool)
    return np.array([str(v).strip().lower() in ("false", "0", "0.0", "no") for v in frame[col]], bool)


def _trade_figure(name, frame, x, y, rel, provenance):
    t = frame.copy()
    for c in (x, y):
        t[c] = np.asarray(t[c].map(lambda v: float(v) if str(v).strip() not in ("", "nan") else np.nan), float)
    labels = _option(frame)
    failed = failed_rows(frame)
    fig, ax = subplots(width_in=5.6, height_in=2.3)
    # options at the same point share one marker named by all of them: four decoder thresholds
    # at (3.36 s, 1.00) were drawn on top of each other and showed as one or two (an outside reader)
    groups: dict = {}
    for lab, xs, ys, bad in zip(labels, t[x], t[y], failed):
        if np.isfinite(xs) and np.isfinite(ys):
            groups.setdefault((float(f"{xs:.3g}"), float(f"{ys:.3g}"), bool(bad)), []).append((lab, xs, ys))
    for k, ((_, _, bad), members) in enumerate(groups.items()):
        _, xs, ys = members[0]
        label = _shared_label([m[0] for m in members]) + (f" ({FAILED_MARK})" if bad else "")
        # a failed fit's point hollow, named so: drawn like a passing one, emcee's point of a fit
        # whose verdict failed read as a result (an outside walk-through)
        ax.plot(xs, max(ys, 1e-6) if y in ERROR_COLS else ys, "os^vD<>"[k % 7], color=f"C{k % 10}", ms=6,
                label=label, **({"markerfacecolor": "none", "markeredgewidth": 1.3} if bad else {}))
    shared = sum(len(m) > 1 for m in groups.values())
    log_axis(ax, "x")
    ys = t[y].to_numpy(float)
    if y in ERROR_COLS and np.all(ys[np.isfinite(ys)] > 0) and np.nanmax(ys) > 10 * np.nanmin(ys):
        log_axis(ax, "y")
    ax.set(xlabel=_AXIS.get(x, x.replace("_", " ")), ylabel=_AXIS.get(y, y.replace("_", " ")),
           title=_TITLES.get(name, name))
    handles, names = ax.get_legend_handles_labels()
    fig.legend(handles, names, loc="outside right upper", fontsize=6, frameon=False,
               ncols=-(-len(names) // LEGEND_ROWS))
    same = " Options at the same point (to 3 significant figures) share a marker, named by all of them." if shared else ""
    bad = (" Hollow markers: fits that failed their verdict (ok False in the table): their numbers are not results."
           if any(bad for _, _, bad in groups) else "")
    return make_figure(_TITLES.get(name, name), fig, (rel,), f"One point per option; {provenance}.{same}{bad}")


#: a benchmark's spread columns, the same number as its median when every row ran one round
_ONE_ROUND = ("min_s", "mean_s", "q1_s", "q3_s", "rounds")


def table_columns(frame) -> list[str]:
    """The columns of a benchmark table to show: not ``measured_at`` (in the provenance line),
    and, when every row ran one round, the median alone of the timing columns (the open-world
    table, one round a scene, ran past the page's right edge with all of them)."""
    one_round = "rounds" in frame.columns and bool((frame["rounds"].fillna(1) <= 1).all())
    return [c for c in frame.columns if c != "measured_at" and not (one_round and c in _ONE_ROUND)]


def _tables(inv, part, names, provenance) -> list:
    """Each table's trade figure (when it has one) and the table. ``provenance``: the words
    of the figures' captions, or a function of a table's time column giving them (the demo's:
    its latency is scan time, its other times wall seconds)."""
    blocks = []
    for name in names:
        rel = part.path(name)
        frame = run_table(inv, rel)
        stem = name.removesuffix(".csv")
        if frame.empty:
            blocks.append(Note(f"{rel}: no rows.", sources=(rel,)))
            continue
        x, y = trade_columns(frame)
        if x and y and len(frame) > 1:
            blocks.append(_trade_figure(stem, frame, x, y, rel, provenance(x) if callable(provenance) else provenance))
        failed = failed_rows(frame)
        blocks.append(table_from_frame(frame[table_columns(frame)], title=_TITLES.get(stem, stem), sources=(rel,),
                                       digits=3, marks=tuple("failed" if f else "" for f in failed),
                                       caption=("Rows marked (ok False): fits that failed their verdict; their numbers are not results."
                                                if failed.any() else "")))
    return blocks


#: time columns that are not wall seconds of a computation: the live decoder's latency is the
#: scan's own time since the stage passed the step
SCAN_TIME_COLS = ("latency_s", "decision_latency_s")


def _demo_times(x: str) -> str:
    """What a demo table's time column measures, for its figure's caption."""
    return ("latency in scan time since the stage passed the step (not wall time)" if x in SCAN_TIME_COLS
            else "times in wall seconds on this machine")


def _bench_blocks(inv, part) -> list:
    names = list(part.files)
    stamp = ""
    if "ratios.csv" in names:
        ratios = run_table(inv, part.path("ratios.csv"))
        stamps = sorted(set(ratios["measured_at"].astype(str))) if "measured_at" in ratios and len(ratios) else []
        stamp = (f" at {stamps[0]}" if len(stamps) == 1 else
                 f" in {len(stamps)} runs from {stamps[0]} to {stamps[-1]} (each row's time in ratios.csv)" if stamps
                 else "")
    provenance = f"measured by `make bench`{stamp}"
    return [Note(f"Tables of {part.label}: {provenance}.", level="measured",
                 sources=tuple(part.path(n) for n in names))] + _tables(inv, part, names, provenance)


def _demo_index(inv, part) -> tuple[dict, list[str]]:
    """(speed.json, the names of its tables present beside it)."""
    from feeler.errors import DataFileError

    rel = part.path("speed.json")
    index = run_json(inv, rel, ("measured", "tables"))
    tables = index["tables"]
    if not isinstance(tables, dict) or not all(isinstance(k, str) and (v is None or isinstance(v, str))
                                               for k, v in tables.items()):
        raise DataFileError(inv.run_dir / rel, f"tables holds {tables!r:.40}; expected an object of table name -> "
                                               f"what it measured (text), as `feeler demo` writes it")
    for key in ("measured", "times"):
        if index.get(key) is not None and not isinstance(index[key], str):
            raise DataFileError(inv.run_dir / rel, f"{key} holds {index[key]!r:.40}; expected text")
    return index, [f"{n}.csv" for n in tables if inv.has(part.path(f"{n}.csv"))]


def speed_inputs(inv, spec) -> None:
    """Read every table the section shows before the report's first figure: `make bench`'s
    tables, the demo's speed.json with its tables, each ladder's files."""
    from feeler.reports.sec_finger import ladder_files

    for part in spec.parts:
        if part.kind == "benchmarks":
            names = list(part.files)
        elif part.kind == "speed":
            names = _demo_index(inv, part)[1]
        else:
            ladder_files(inv, part)
            continue
        for name in names:
            run_table(inv, part.path(name))


def _demo_blocks(inv, part) -> list:
    rel = part.path("speed.json")
    index, names = _demo_index(inv, part)
    times = f"; {index['times']}" if index.get("times") else ""
    provenance = f"measured {index['measured']}{times}: a small version, `make bench` measures the full one"
    blocks = [Note(f"{provenance[0].upper()}{provenance[1:]}.", level="measured", sources=(rel,))]
    for name, what in dict(index["tables"]).items():
        if what:
            blocks.append(Note(f"{name}: {what}", sources=(part.path(f"{name}.csv"),)))
    # each figure's caption says what its own times are: the calibration backends' and the sensor
    # fidelities' said "... but the live decoder's latency, which is scan time since the step"
    # (speed.json's "times", which is of the whole set: an outside walk-through)
    short = f"measured {index['measured']}: a small version, `make bench` measures the full one"
    return blocks + _tables(inv, part, names, lambda x: f"{short}; {_demo_times(x)}")


def times(ratio: float) -> str:
    """A speed-up in plain digits: 1549 (not "1.55e+03"), 156, 1.96."""
    return f"{ratio:,.0f}" if ratio >= 100 else fmt(ratio, 3)


def speed_section(inv, spec) -> Section:
    from feeler.reports.finger_plots import mesh_name
    from feeler.reports.sec_finger import ladder_files

    blocks = []
    for part in spec.parts:
        if part.kind == "benchmarks":
            blocks += _bench_blocks(inv, part)
        elif part.kind == "speed":
            blocks += _demo_blocks(inv, part)
    for part in (p for p in spec.parts if p.kind == "ladder"):
        rel = part.path("trade.csv")
        t, info = ladder_files(inv, part)
        ref = t["seconds_per_slide"].max()
        met = info.get("met") if isinstance(info.get("met"), dict) else {}
        converged = bool(met["convergence"]) if "convergence" in met else None
        words = "; ".join(f"{r.level.upper()} ({mesh_name(str(r.mesh), converged)}) "
                          f"{times(ref / r.seconds_per_slide)}× faster at "
                          f"{fmt(100 * r.rate_error, 2)} % error" for r in t.itertuples(index=False)
                          if r.seconds_per_slide < ref)
        blocks.append(Note(f"Skin ladder ({part.label}), against its slowest rung: {words}. Plotted with its table "
                           "in the finger section.", sources=(rel,)))
    if not any((inv.run_dir / p.path("decoder.csv")).is_file() for p in spec.parts):
        blocks.append(Note("The live decoder's decision latency against accuracy appears here when the run holds "
                           "its trade table (decoder.csv in benchmarks/ or speed/: columns option, latency_s, "
                           "accuracy)."))
    return Section(spec.key, spec.title, tuple(blocks))
