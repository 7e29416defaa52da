"""Run an acquisition campaign (a scan plan) on the stage and the tactile camera.

  feeler acquire --stage /dev/ttyUSB0 --camera 0 --plan PLAN.toml --out RUN
  feeler acquire --stage /dev/ttyUSB0 --camera 0 --plan PLAN.toml --out RUN --home   # $22=1 boards
  feeler acquire --emulate --plan PLAN.toml --out RUN       # emulated stage + virtual camera
  feeler acquire --emulate --plan PLAN.toml --out RUN --resume   # continue an interrupted run

The stage is a Grbl 1.1 board; the plan's positions are its machine coordinates (Grbl's
convention: [-travel, 0] per axis). A board with homing enabled ($22=1) powers up locked:
--home runs its homing cycle ($H), --unlock clears the lock without homing ($X); without
either, acquire stops with a one-line error before anything moves. Every move of the plan is
checked against the board's soft limits and the axes' maximum rates ($110-$112) first.

--camera is a device index, a video file or an image sequence (frames/%05d.png). With
--emulate a Grbl emulator runs on a pty in a child process and, without --camera, a virtual
camera renders the optical sensor for the stage's position over the plan's plate
(recording RUN/video/scan_NNNN.avi, lossless FFV1; each replays its scan with --camera under
a plan of that one scan, and a source with fewer frames than the plan has samples is refused
before the stage moves).

RUN/samples.csv receives every sample as it arrives (flushed and fsync-ed), RUN/scans.csv
every complete scan in the format of `feeler simulate` (scan_id, plate, step_mm, speed_mm_s,
t_s, x_mm, ux_mm, uy_mm, uz_mm, then the schedule, the status query's round trip, the late
flag, stage position, frame time, areas and forces), and RUN/scene.toml is the plan
(RUN/layout.toml its camera layout, so that `--resume --plan RUN/scene.toml` works):
`feeler calibrate neuron RUN` reads the run directly. t_s is when the position was read,
from the start of the traverse; a sample read more than --late-fraction of a period after its
schedule is counted late (never relabelled). One process writes RUN at a time (a second one
is refused, naming the first one's PID). After a crash, --resume continues with the scans not
yet done; Ctrl-C or SIGTERM stop a run cleanly (exit 130, RUN/summary.json says where). Bad
frames and bad status lines are logged, counted and never used; RUN/summary.json reports the
counts. Displacement is read as U = C F with C the posterior mean of an M1 fit
(--calibration DIR) or the nominal optics. Progress goes to stderr: a live line on a
terminal, a line per finished scan otherwise (--no-progress: none). --realtime runs the
acquisition loop (frames, areas, decoding) at real-time priority where the system permits
it (root, CAP_SYS_NICE or `ulimit -r`), so that a busy machine does not delay a frame by a
scheduler tick; stderr says whether it was granted, and without it the run goes on as usual.
"""
from __future__ import annotations

import argparse

NAME = "acquire"
HELP = "run a scan plan on the stage and camera (or --emulate) into a run directory"
__all__ = ["NAME", "HELP", "register", "run"]


def register(parser) -> None:
    parser.add_argument("--plan", required=True, metavar="PLAN", help="scan-plan TOML file")
    parser.add_argument("--out", required=True, metavar="RUN", help="run directory")
    parser.add_argument("--stage", metavar="PORT", default=None,
                        help="serial port of the Grbl stage (device path or pyserial URL)")
    parser.add_argument("--camera", metavar="SRC", default=None,
                        help="camera index, video file or image-sequence pattern")
    parser.add_argument("--emulate", action="store_true",
                        help="emulated stage on a pty (and a virtual camera unless --camera)")
    parser.add_argument("--fault", action="append", default=[], metavar="SPEC",
                        help="with --emulate: inject a stage fault, as `feeler emulate stage --fault`")
    parser.add_argument("--resume", action="store_true", help="continue an interrupted run in RUN")
    parser.add_argument("--calibration", metavar="DIR", default=None,
                        help="M1 fit directory (feeler calibrate sensor --out DIR): read U with its C")
    parser.add_argument("--force", action="store_true", help="overwrite an earlier run in RUN")
    parser.add_argument("--home", action="store_true", help="home the stage first ($H; unlocks a $22=1 board)")
    parser.add_argument("--unlock", action="store_true",
                      help="clear the stage's alarm lock without homing ($X; positions not re-referenced)")
    parser.add_argument("--late-fraction", type=float, default=0.25, metavar="F",
                        help="a sample read more than F sample periods after its schedule is late (default 0.25)")
    parser.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None,
                        help="progress on stderr (default: live on a terminal, a line per scan otherwise)")
    parser.add_argument("--decode", metavar="FIT_DIR", default=None,
                        help="decode every scan while acquiring with this neuron fit (feeler calibrate neuron "
                             "--out, on scans of this set-up; with --emulate, on an emulated run: README, 'Which "
                             "fit to decode with'): RUN/decisions.csv, as `feeler decode`, and a line per decision "
                             "on stderr (none with --no-progress); with --resume the scans acquired before are "
                             "decoded first, so decisions.csv holds every scan of the run")
    parser.add_argument("--accept-failed", action="store_true",
                        help="use a --calibration or --decode fit that failed its diagnostics")
    parser.add_argument("--realtime", action="store_true",
                        help="run the acquisition loop at real-time priority (SCHED_FIFO 10) if the system "
                             "permits: root, CAP_SYS_NICE or ulimit -r; otherwise say why and run as usual")
    parser.set_defaults(run=run)


def _interrupt(signum, frame):
    raise KeyboardInterrupt(f"signal {signum}")


def run(args) -> int:
    import contextlib
    import logging
    import signal
    import sys

    from feeler.errors import ArgumentError
    from feeler.hardware.acquire import acquire
    from feeler.hardware.acquire.progress import Progress
    from feeler.hardware.emulators import parse_fault

    signal.signal(signal.SIGTERM, _interrupt)      # stop like Ctrl-C: the summary says why
    if args.emulate and args.stage is not None:
        raise ArgumentError("--stage", args.stage, "no port with --emulate (the emulator provides one)")
    observers = () if args.progress is False else (Progress(live=None if args.progress is None else True),)
    decoding = ()
    if args.decode:                                # the fit is checked before anything moves
        from feeler.calib.neuron.live.observer import decode_observer
        decoding = (decode_observer(args.decode, args.out, observers, force=args.force or args.resume,
                                    accept_failed=args.accept_failed, progress=args.progress is not False),)
    with contextlib.ExitStack() as stack:          # undone in reverse: priority first, then the log filters
        for progress in observers:
            for handler in logging.getLogger().handlers:
                handler.addFilter(progress.clear)
                stack.callback(handler.removeFilter, progress.clear)
        if args.realtime:
            from feeler.hardware.realtime import DEFAULT_PRIORITY, realtime_priority

            refused = stack.enter_context(realtime_priority())
            print(f"feeler: {refused}; acquiring at the normal priority" if refused else
                  f"feeler: acquisition loop at real-time priority (SCHED_FIFO {DEFAULT_PRIORITY})", file=sys.stderr)
        summary = acquire(args.plan, args.out, stage_port=args.stage, camera_src=args.camera,
                          emulate=args.emulate, resume=args.resume, force=args.force,
                          calibration=args.calibration, accept_failed=args.accept_failed,
                          emulator_faults=tuple(parse_fault(spec) for spec in args.fault),
                          unlock=args.unlock, home=args.home, late_fraction=args.late_fraction,
                          observers=observers + decoding)
    print(summary_line(args.out, summary))
    return 0 if summary["complete"] else 1


def counted(n: int, noun: str, plural: str | None = None) -> str:
    """``1 bad line``, ``2 bad lines``."""
    return f"{n} {noun if n == 1 else plural or noun + 's'}"


def summary_line(out, summary: dict) -> str:
    """acquire's last line: the counts of ``summary.json``, singular or plural as they come,
    and where a slow scan is told of (it read "1 scans ... (see the log)", naming no log)."""
    from pathlib import Path

    state = "complete" if summary["complete"] else "incomplete"
    line = (f"{out}: {summary['scans_done']} of {summary['scans_planned']} scans ({state}), "
            f"{counted(summary['samples_written'], 'sample')}, {counted(summary['bad_frames'], 'bad frame')}, "
            f"{counted(summary['bad_lines'], 'bad line')}, {counted(summary['late_samples'], 'late sample')}, "
            f"{counted(summary['partial_lines_dropped'], 'partial line', 'partial lines')} dropped")
    slow = summary.get("slow_scans")
    if slow:
        line += (f"; {counted(slow, 'scan')} where the stage moved slower than planned (the warning"
                 f"{'s' if slow != 1 else ''} above, and slow_scan events in {Path(out) / 'journal.jsonl'})")
    return line
