"""Decode a run's scans sample by sample, as a robot would while it scans.

POSTERIOR is a directory written by `feeler calibrate neuron --out`; RUN a run directory
(`feeler simulate`, `feeler acquire`) or a scan CSV (README, "Scan CSV format"). Each
scan is fed to the streaming decoder one sample at a time; a scan is decided at the
first sample where its response has passed its peak (fallen below 1 − --drop of its
maximum) and the most probable plate has probability >= --threshold; the lowest plate
only at the scan's end (before the step the response looks like it), a scan flagged as
unlike the fit's training scans not while it is flagged (a flag the rest of the scan
raises comes after its decision: the summary counts such scans, and a decision of a
flagged scan does not hold); before its 20th sample, not while one sample
stands off both neighbours by half the scan's rise (a possible glitch, too early to
judge). Writes RUN/decisions.csv (or into --out DIR; next to a CSV given as RUN): per
scan the probability of every plate and the decoded height with its 90 % interval at the
scan's end (equal to `feeler classify`), the decision (plate, probability, time and stage
position; empty if none), and whether the scan was flagged, with the reason. The batch's
read-out noise is judged as classify judges it, after every scan over the scans so far:
once they show a noisier (or far quieter) set-up than training, every scan is flagged with
that reason and the later ones are not decided; at the end the flags equal classify's. With
labels, a warning when the decisions were right less often than the probabilities they
were taken at promised, or the intervals held for too few labels (README, "Scan CSV
format"); as classify, a note on scans of a mode the fit reads no better than its plates'
shares, on a batch a fifth or more of whose scans (of 20 or more) read far from every
trained plate (another scale, or steps the fit was not trained on), on scans that copy
another's U_y, and on intervals wider than they claim.

A fit decodes scans of the set-up it was calibrated on: for an emulated run (`feeler
acquire --emulate`) calibrate on an emulated run (README, "Which fit to decode with").

--follow decodes a run another process is still acquiring: it tails RUN/samples.csv
(a partial last line waits for its end) and stops when the acquisition lets go of the
run (finished, stopped or crashed), rewriting decisions.csv after every scan; a scan the
acquisition cut short gets no row (as without --follow). RUN may not exist yet: --wait-s
waits for it (a follower started before `feeler acquire`). On a
terminal a live line shows the scan in progress (decoded z so far, plate
probabilities, decision); otherwise one line per decision (--no-progress: neither).
"""
from __future__ import annotations

import argparse

from feeler.commands._posterior_use import add_use_arguments, load_checked

__all__ = ["NAME", "HELP", "register", "run"]

NAME = "decode"
HELP = "decode a run's scans sample by sample (decisions.csv), also while it is acquired (--follow)"


def register(parser) -> None:
    add_use_arguments(parser, n_draws=400, out_file="decisions.csv")
    parser.add_argument("run_dir", metavar="RUN", help="run directory (scans.csv or samples.csv), or a scan CSV")
    parser.add_argument("--follow", action="store_true", help="tail RUN/samples.csv until the acquisition ends")
    parser.add_argument("--threshold", type=float, default=0.9,
                        help="decide when the top plate's probability reaches this, after the peak (default 0.9; "
                             "at most 1 - 0.001*(plates-1)/plates, the fit's floor)")
    parser.add_argument("--drop", type=float, default=0.5,
                        help="the peak has passed once the response fell by this fraction (default 0.5)")
    parser.add_argument("--poll-s", type=float, default=None, help="--follow: seconds between looks (default 0.2)")
    parser.add_argument("--wait-s", type=float, default=None,
                        help="--follow: how long to wait for RUN and its samples.csv to appear (default 30 s)")
    parser.add_argument("--live", action=argparse.BooleanOptionalAction, default=None,
                        help="one live line per scan (default: when stderr is a terminal)")
    parser.set_defaults(run=run)


#: --follow's options and their defaults (s)
FOLLOW_ONLY = {"poll_s": 0.2, "wait_s": 30.0}


def run(args) -> int:
    from pathlib import Path

    from feeler.commands._checks import refuse_unused
    from feeler.errors import ArgumentError, OverwriteError
    from feeler.rundir import prepare_out_dir

    path = Path(args.run_dir)
    refuse_unused(args, FOLLOW_ONLY, used=args.follow, needs=lambda name: "needs --follow (a finished run is read "
                                                                          "at once)")
    if not args.poll_s > 0:
        raise ArgumentError("--poll-s", args.poll_s, "> 0 s")
    if not 0 < args.threshold <= 1:                 # with the option's name, before anything is read
        raise ArgumentError("--threshold", args.threshold, "a probability in (0, 1]")
    if not 0 < args.drop < 1:
        raise ArgumentError("--drop", args.drop, "a fraction in (0, 1)")
    if args.follow and not args.wait_s >= 0:
        raise ArgumentError("--wait-s", args.wait_s, ">= 0 s")
    if args.follow and not path.exists():               # started just before the acquisition: wait for it
        _wait_for_run(path, args)
    if args.follow and not path.is_dir():
        raise ArgumentError("RUN", str(path), "a run directory with --follow (one that `feeler acquire` writes)")
    if not args.follow and not path.exists():
        raise ArgumentError("RUN", str(path), "an existing run directory or scan CSV")
    out = Path(args.out) if args.out else (path if path.is_dir() else path.parent)
    try:
        out = prepare_out_dir(out, ("decisions.csv",), force=args.force)
    except OverwriteError as exc:                       # e.g. following a run again after `acquire --resume`
        raise OverwriteError(exc.path, "pass --force to replace it (the run is decoded again from its first "
                                       "scan, as after `feeler acquire --resume`)") from None
    records = None
    if not args.follow:
        from feeler.calib.neuron.live.scan_csv import read_scan_records
        records = read_scan_records(path)                 # a bad file fails before the fit loads
        if records and records[0].file:
            print(f"{path}: {len(records)} scan files in name order ({records[0].file} ... {records[-1].file}) "
                  f"read as scan_id {records[0].scan_id} ... {records[-1].scan_id}; decisions.csv names them by "
                  f"scan_id")
        elif records and records[0].name is not None:
            print(f"{path}: scan ids are names ({records[0].name} ... {records[-1].name}), read as scan_id "
                  f"{records[0].scan_id} ... {records[-1].scan_id} in order of appearance; decisions.csv names "
                  f"them by that number")
    decoder = _decoder(args)
    if args.follow:
        _follow(decoder, path, out, args)
    else:
        from feeler.calib.neuron.live.follow import writer_active
        if path.is_dir() and writer_active(path):
            print(f"{path} is still being acquired: decoding the scans written so far (--follow keeps up)")
        for r in records:
            for k in range(r.t_s.size):
                decoder.sample({"scan_id": r.scan_id, "t_s": r.t_s[k], "uy_mm": r.uy_mm[k],
                                "x_mm": None if r.x_mm is None else r.x_mm[k], "step_mm": r.step_mm,
                                "speed_mm_s": r.speed_mm_s})
            decoder.end_scan()
        decoder.write(out / "decisions.csv")
    _summary(decoder)
    print(f"wrote {out / 'decisions.csv'}")
    return 0


def _decoder(args):
    from feeler.calib.neuron.live import LiveDecoder
    from feeler.calib.neuron.live.run import RunDecoder
    from feeler.calib.neuron.live.show import LiveView

    live = LiveDecoder(load_checked(args), seed=args.seed, n_draws=args.n_draws, threshold=args.threshold,
                       drop=args.drop)
    if live.dec.note:
        print(live.dec.note)
    if args.progress is False:                          # --no-progress: no live line, no line per decision
        return RunDecoder(live)
    view = LiveView(live.plates_mm, live=args.live)
    return RunDecoder(live, on_state=view.on_state, on_scan=view.on_scan)


def _follow(decoder, path, out, args) -> None:
    from feeler.calib.neuron.live.follow import follow_rows

    stats: dict = {}
    write = decoder.on_scan

    def on_scan(row):
        if write is not None:                           # None: --no-progress
            write(row)
        decoder.write(out / "decisions.csv")

    decoder.on_scan = on_scan
    try:
        for row in follow_rows(path, poll_s=args.poll_s, wait_s=args.wait_s, stats=stats):
            decoder.sample(row)
    except KeyboardInterrupt:
        print("\ninterrupted: the scan in progress is decoded as far as it went")
    else:
        _drop_cut_scan(decoder, path)
    decoder.end_scan()
    decoder.write(out / "decisions.csv")
    if stats.get("partial_lines_dropped"):
        print("the run ended with a cut last line in samples.csv: that sample was not decoded")


def _wait_for_run(path, args) -> None:
    """Wait up to --wait-s for RUN to appear (a follower started before `feeler acquire` has
    made it); refuse naming the wait when it does not."""
    import sys
    import time

    from feeler.errors import ArgumentError

    if args.progress is not False:
        print(f"waiting up to {args.wait_s:g} s for {path} to appear (--wait-s) ...", file=sys.stderr, flush=True)
    deadline = time.monotonic() + args.wait_s
    while not path.exists():
        if time.monotonic() >= deadline:
            raise ArgumentError("RUN", str(path), f"a run directory: none appeared in {args.wait_s:g} s (--wait-s); "
                                "start `feeler acquire --out RUN` too, or give a longer --wait-s")
        time.sleep(args.poll_s)


def _drop_cut_scan(decoder, path) -> None:
    """The acquisition let go of the run in the middle of a scan (stopped or crashed): that
    scan is not complete, and gets no row, as `decode` of the run (its scans.csv) leaves it
    out; `feeler acquire --resume` scans it again."""
    from feeler.calib.neuron.live.follow import completed_scans

    done = completed_scans(path)
    sid = decoder.in_progress
    if done is None or sid is None or sid in done:
        return
    decoder.discard()
    decoder.forget(sid)                                 # an earlier attempt of it, cut too
    print(f"scan {sid} was cut short when the acquisition stopped: it gets no row in decisions.csv (as `feeler "
          f"decode` of the run leaves it out); `feeler acquire --resume` scans it again")


def _summary(decoder) -> None:
    import numpy as np

    from feeler.calib.neuron.live.table import claims_check, copies_note, coverage_note, off_plate_note, on_a_plate
    from feeler.calib.neuron.classify import chance_mode_notes

    t = decoder.table()
    if t.empty:
        print("no scans decoded")
        return
    decided = np.isfinite(t["decided_mm"].to_numpy(float))
    line = f"{len(t)} scans: {decided.sum()} decided"
    if "step_mm" in t.columns and decided.any():
        hit = np.isclose(t["decided_mm"].to_numpy(float)[decided], t["step_mm"].to_numpy(float)[decided])
        line += f", {hit.mean() * 100:.1f} % of decisions the labelled plate"
        line += f"; median decision at {np.median(t['decided_at_t_s'].to_numpy(float)[decided]):.3g} s"
    flagged = int(t["flagged"].sum())
    print(line + (f"; {flagged} flagged as unlike the fit's training scans" if flagged else ""))
    if decoder.batch:                                   # as classify: every scan, with the batch's reason
        print(f"note: every scan is flagged: {decoder.batch}")
    late = int(np.sum(decided & t["flagged"].to_numpy(bool)))
    if late:
        why = ("later in the scan (the rest of it showed what its first samples had not)" if not decoder.batch else
               "after the decision (later in the scan, or with the batch's read-out noise once enough scans were "
               "in to tell)")
        print(f"note: {late} decided scan{'s were' if late > 1 else ' was'} flagged {why}; see the flag column: "
              f"those decisions do not hold")
    off = off_plate_note(sum(decoder.off_plate[k] for k in decoder.rows), len(t), decoder.live.env.plate_sds,
                         "probabilities and decisions")
    if off:
        print(off)
    if "step_mm" in t.columns:                          # a run of other plates than the fit's (another scene)
        plates = np.asarray(decoder.live.plates_mm, float)
        step = t["step_mm"].to_numpy(float)
        new = np.isfinite(step) & ~on_a_plate(step, plates)
        if new.any():
            print(f"note: {int(new.sum())} of {len(t)} scans are labelled with steps the fit has no plate for "
                  f"({', '.join(f'{v:g}' for v in np.unique(step[new]))} mm; its plates: "
                  f"{', '.join(f'{v:g}' for v in plates)} mm): none of them can be decided as its label")
    keys = [decoder.uy_key[k] for k in sorted(decoder.rows) if k in decoder.uy_key]
    copies = copies_note([f"scan_id {k}" for k in sorted(decoder.rows) if k in decoder.uy_key], keys)
    if copies:
        print(copies)
    snapped = [decoder.snapped[k] for k in sorted(decoder.rows)]
    modes = None if None in snapped else np.array(snapped, bool)
    for said in chance_mode_notes(decoder.live.fit.posterior["posterior"].attrs, modes):
        print(f"note: {said}")
    for said in claims_check(t, decoder.live.plates_mm, decided="decided_mm", promised="p_decided"):
        print(f"warning: {said}")
    wide = coverage_note(t, decoder.live.plates_mm)
    if wide:
        print(f"note: {wide}")
