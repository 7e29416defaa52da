"""Classify new plate scans with a calibrated neuron (M2 posterior).

POSTERIOR is a directory written by `feeler calibrate neuron --out`; SCANS a run directory
or a scan CSV: scan_id, t_s (s), uy_mm (mm) are required; x_mm (mm) checks the stage speed;
step_mm and speed_mm_s are labels that add the accuracy and coverage summary (README,
"Scan CSV format"), with a warning when the labels contradict the fit: too few inside
their 90 % intervals, or fewer classified right than the probabilities promised. Strain
uses the posterior's representative length. A scan unlike the fit's training scans
(speed, sampling period, length, response scale, read-out noise; a whole batch noisier
than the training scans; a one-sample spike; a reading far from every trained plate; U_y
falling where a touch rises) is flagged with the reason, and a note says when a fifth or
more of a batch of 20 or more scans reads far from every plate; one whose times
or displacements look like the wrong units is refused. For each scan: the probability of
every training plate and the decoded step height with its 90 % interval (inverting each
plate's predictive band: at any true step the interval covers it 90 % of the time),
integrating over the posterior. A posterior that failed its diagnostics is refused unless
--accept-failed. --out DIR writes classification.csv. A note names the scans of a mode
(snaps, rides) whose training scans the fit reads no better than their plates' shares, and
another the scans that repeat an earlier scan's U_y at every sample (copies).
"""
from __future__ import annotations

from feeler.commands._posterior_use import add_use_arguments, load_checked

__all__ = ["NAME", "HELP", "register", "run"]

NAME = "classify"
HELP = "plate probabilities and decoded step heights of new scans, from a neuron posterior"
FLAG_LINES = 10          # flagged scans named on screen; the rest are counted (all are in the CSV)


def register(parser) -> None:
    add_use_arguments(parser, n_draws=400, out_file="classification.csv")
    parser.add_argument("scans", metavar="SCANS", help="run directory with scans.csv, or the CSV")
    parser.add_argument("--backend", choices=("draws",), default="draws",
                        help="draws: Monte Carlo over posterior draws (the only one)")
    parser.set_defaults(run=run)


def run(args) -> int:
    from pathlib import Path

    import numpy as np
    import pandas as pd

    from feeler.calib.neuron.classify import chance_mode_notes, classify
    from feeler.calib.neuron.live.envelope import Envelope, readout_noise_mm, with_batch
    from feeler.calib.neuron.live.scan_csv import read_scan_records
    from feeler.calib.neuron.live.table import (claims_check, copies_note, coverage_note, labelled_summary,
                                                off_plate_note, plate_column, unit_mistake)
    from feeler.rundir import prepare_out_dir

    from feeler.commands._checks import check_out_dir

    path = Path(args.scans)
    if args.out:                                   # every argument checked before any work
        check_out_dir(args.out, ("classification.csv",), force=args.force)
    result = load_checked(args)                    # POSTERIOR first, as on the command line
    from feeler.calib.progress import stage

    stage(f"reading {path}", args.progress)
    records = read_scan_records(path)
    length = float(result.posterior["posterior"].attrs["length_mm"])
    stage(f"decoding {len(records)} scans with {args.n_draws} posterior draws", args.progress)
    c = classify(result, [r.uy_mm / length for r in records], [r.t_s for r in records],
                 rng=np.random.default_rng(args.seed), n_draws=args.n_draws, progress=args.progress)
    env = Envelope.of_fit(result, c.tau_s)
    noise = [readout_noise_mm(r.uy_mm) for r in records]
    batch = env.batch_noise(noise)                  # a noisier (or far quieter) set-up: every scan, as decode
    flags = [with_batch(env.problems(r.t_s, c.p_at_tau[:, k], x_mm=r.x_mm, speed_mm_s=r.speed_mm_s, uy_mm=r.uy_mm)
                        + [f for f in [env.plates(c.plate_sds[k], c.nearest_mm[k], c.height_mm[k]),
                                       env.falling(r.uy_mm, c.plates_mm, c.height_mm[k])] if f],
                        env.noise(noise[k]), batch)
             for k, r in enumerate(records)]
    unit_mistake(path, [f"scan file {r.file}" if r.file else f"scan_id {r.scan_id if r.name is None else repr(r.name)}"
                        for r in records], flags, result.verdict.problems)
    labels = {"step_mm": [np.nan if r.step_mm is None else r.step_mm for r in records]}
    table = pd.DataFrame({"scan_id": [r.scan_id if r.name is None else r.name for r in records],
                          **({"file": [r.file for r in records]} if any(r.file for r in records) else {}),
                          **(labels if any(r.step_mm is not None for r in records) else {}),
                          "plate_mm": c.plate_mm, **{plate_column(v): c.prob[:, i] for i, v in enumerate(c.plates_mm)},
                          "height_mm": c.height_mm, "lo90_mm": c.lo90_mm, "hi90_mm": c.hi90_mm,
                          "flagged": [bool(f) for f in flags], "flag": ["; ".join(f) for f in flags]})
    with pd.option_context("display.width", 160, "display.max_rows", 60, "display.max_colwidth", 60):
        print(table.drop(columns="flag").to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    flagged = [(sid, f) for sid, f in zip(table.scan_id, flags) if f]
    for sid, f in flagged[:FLAG_LINES]:
        print(f"scan {sid} flagged: {'; '.join(f)}")
    if len(flagged) > FLAG_LINES:
        where = (f"the flag column of {Path(args.out) / 'classification.csv'}" if args.out
                 else "the flag column of the classification.csv that --out DIR writes")
        print(f"... {len(flagged) - FLAG_LINES} more flagged scans ({len(flagged)} of {len(table)} in all); "
              f"every scan's reason is in {where}")
    off = off_plate_note(int(np.sum(c.plate_sds > env.plate_sds)), len(table), env.plate_sds)
    if off:
        print(off)
    copies = copies_note([f"scan_id {v}" for v in table["scan_id"]], [r.uy_mm for r in records])
    if copies:
        print(copies)
    if c.note:
        print(c.note)
    for line in chance_mode_notes(result.posterior["posterior"].attrs, c.snap):
        print(f"note: {line}")
    summary = labelled_summary(table, c.plates_mm)
    print(summary or f"{len(table)} unlabelled scans (no step_mm column): no accuracy to report")
    for line in claims_check(table, c.plates_mm):
        print(f"warning: {line}")
    wide = coverage_note(table, c.plates_mm)
    if wide:
        print(f"note: {wide}")
    if args.out:
        out = prepare_out_dir(args.out, ("classification.csv",), force=args.force)
        table.to_csv(out / "classification.csv", index=False)
        print(f"wrote {out / 'classification.csv'}")
    return 0

