"""Build the HTML and PDF report of a run directory.

RUN_DIR is any directory of runs: one command's output (a fit, a simulation, an
acquisition, a skin study), the whole of `feeler demo`, or a mix under any names — the
report recognises each part by its files. The first page answers "did it reproduce the
paper, and what did it find": the paper's claims checked one by one against the run
(number, 95 % interval, mark), every fit's verdict (a failed one first), and what each
missing part would need: commands that read the run's own fit, scans or trials and write
into new directories (beside RUN_DIR when it is one command's output, such as a fit or a
simulation, which holds that output only). Then one section per part, failed
calibrations first.

Writes report.html (self-contained: figures inlined, opens offline), report.pdf (the same
HTML laid out by WeasyPrint) and report-manifest.json (every figure with the files it
came from). Progress: a live line on a terminal, otherwise a line per stage: each
section, each figure drawn, each PDF step and page (--no-progress: none). A corrupt file
of the run stops with a one-line error naming it (exit 2) before any figure is drawn (every
file the report uses is read first), and so does a directory holding nothing the report
can show. Otherwise the exit status is 0 once the report is written,
whatever the verdicts it holds: a failed fit is a result to show (first, and named on
stdout as "FAILED calibration shown first: ..."), not a failure of the report. Files of
other commands the report does not read (decode's decisions.csv, validate sbc's ranks.csv
and sbc.csv) are named on stderr: "not reported: ...". The three files are put in place
together at the end: Ctrl-C (exit 130) leaves an earlier report as it was, and one line
says so.

Examples:
    feeler report runs/demo
    feeler report runs/demo/m1 --no-pdf
    feeler report runs/acquired --out /tmp/acquired-report
"""
from __future__ import annotations

__all__ = ["NAME", "HELP", "register", "run", "check_out_dir"]

NAME = "report"
HELP = "build report.html and report.pdf from any run directory (a fit, a simulation, an acquisition, the demo)"


def register(parser) -> None:
    parser.add_argument("run_dir", metavar="RUN_DIR", help="run directory (any command's output, or several)")
    parser.add_argument("--out", default=None, metavar="DIR",
                        help="where to write report.html, report.pdf, report-manifest.json (default RUN_DIR)")
    parser.add_argument("--no-pdf", action="store_true", help="write only report.html (and the manifest)")
    parser.add_argument("--progress", dest="progress", action="store_true", default=None,
                        help="always show the progress bar (default: on a terminal; a line per stage otherwise)")
    parser.add_argument("--no-progress", dest="progress", action="store_false",
                        help="no progress bar and no stage lines")
    parser.set_defaults(run=run)


def check_out_dir(path) -> None:
    """Refuse an output directory that cannot be written, before any work.

    Raises:
        ArgumentError: ``path`` is a file, or it (or its nearest existing parent) is not writable.
    """
    import os
    from pathlib import Path

    from feeler.errors import ArgumentError

    path = Path(path)
    if path.exists() and not path.is_dir():
        raise ArgumentError("--out", str(path), "a directory (this is a file)")
    probe = path
    while not probe.exists():
        probe = probe.parent
    if not os.access(probe, os.W_OK | os.X_OK):
        raise ArgumentError("--out", str(path), f"a writable directory ({probe} is not writable)")


def _nothing_written(out) -> str:
    """What an interrupted report leaves in ``out``: nothing new, and the earlier report, if any."""
    from feeler.reports.build import OWN_FILES

    earlier = [name for name in OWN_FILES if (out / name).is_file()]
    kept = (f"the earlier {', '.join(earlier)} there are unchanged" if earlier else "there was no report there before")
    return f"no report written to {out} (its files are put in place only once all are done); {kept}"


def run(args) -> int:
    import sys
    from pathlib import Path

    from feeler.errors import DataFileError

    if args.progress is not False:                   # the first line, as feeler.cli prints for the others
        print(f"feeler report: reading {args.run_dir} ...", file=sys.stderr, flush=True)
    if not Path(args.run_dir).is_dir():
        raise DataFileError(args.run_dir, "not a directory; expected a run directory")
    check_out_dir(args.out if args.out is not None else args.run_dir)
    from feeler.reports import build_report

    from feeler.calib.progress import stages

    step, close = stages("report", args.progress)
    try:
        try:
            report = build_report(args.run_dir, args.out, pdf=not args.no_pdf, progress=step)
        finally:
            close()
    except KeyboardInterrupt:                        # the files are put in place only at the end
        print(f"feeler: interrupted: {_nothing_written(Path(args.out or args.run_dir))}", file=sys.stderr)
        return 130
    inv = report.inventory
    if inv.unread:                                   # named, never passed over in silence
        print("not reported: " + ", ".join(f"{rel} ({what})" for rel, what in inv.unread), file=sys.stderr)
    for title in report.failed:
        print(f"FAILED calibration shown first: {title}")
    print(f"holds: {len(inv.parts)} part(s) in {len(inv.present)} section(s)"
          + "".join(f"\n  {s.title}" for s in inv.present))
    for m in inv.missing:
        print(f"not in this run: {m.title} — needs {m.needs}")
    if inv.missing_note:
        print(f"note: {inv.missing_note}")
    problems = [f for f in report.figures if f["layout_problems"]]
    if problems:
        print(f"warning: {len(problems)} figure(s) with layout problems (see {report.manifest.name})")
    print(f"report: {report.html}")
    if report.pdf is not None:
        print(f"report: {report.pdf} ({report.n_pages} pages)")
    elif (report.html.parent / "report.pdf").exists():     # --no-pdf beside an earlier report's PDF
        print(f"note: {report.html.parent / 'report.pdf'} is an earlier report's, not this one's (--no-pdf); "
              "run without --no-pdf to replace it, or remove it")
    print(f"manifest: {report.manifest} ({len(report.figures)} figures)")
    return 0
