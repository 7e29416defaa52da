"""Build the HTML and PDF report of a run directory.

RUN_DIR is a directory written by `feeler demo` or assembled from the outputs of `feeler
simulate`, `calibrate sensor|neuron`, `classify`, `discriminate` and `fit psychophysics`
(synthetic, acquired or mixed). The report shows only the sections whose files exist and
lists the missing ones; a failed calibration is shown first. report.html is
self-contained (figures inlined, no network needed to open it); report.pdf is the same
HTML laid out by WeasyPrint. A corrupt file of the run stops with a one-line error naming
it (exit 2).

Example:
    feeler report runs/demo
"""
from __future__ import annotations

__all__ = ["NAME", "HELP", "register"]

NAME = "report"
HELP = "build report.html and report.pdf from a run directory"


def register(parser) -> None:
    parser.add_argument("run_dir", metavar="RUN_DIR", help="run directory")
    parser.add_argument("--out", default=None, metavar="DIR",
                        help="where to write report.html / report.pdf (default RUN_DIR)")
    parser.add_argument("--no-pdf", action="store_true", help="write only report.html")
    parser.add_argument("--progress", dest="progress", action="store_true", default=None,
                        help="always show the progress bar")
    parser.add_argument("--no-progress", dest="progress", action="store_false",
                        help="never show the progress bar")
    parser.set_defaults(run=run)


def run(args) -> int:
    import sys

    from feeler.calib.progress import show_progress
    from feeler.reports import build_report, discover

    inv = discover(args.run_dir)
    bar = None
    if show_progress(args.progress):
        from tqdm.auto import tqdm
        bar = tqdm(total=len(inv.present) + 2 + (not args.no_pdf), desc="report", file=sys.stderr,
                   leave=False, dynamic_ncols=True)

    def step(stage: str) -> None:
        if bar is not None and stage != "discover":
            bar.set_postfix_str(stage)
            bar.update(1)

    try:
        report = build_report(args.run_dir, args.out, pdf=not args.no_pdf, progress=step)
    finally:
        if bar is not None:
            bar.close()
    for title in report.failed:
        print(f"FAILED calibration shown first: {title}")
    for title, files in report.inventory.missing:
        print(f"missing for '{title}': {', '.join(files)}")
    print(f"sections: {len(report.inventory.present)} shown, {len(report.inventory.missing)} with missing files")
    print(f"report: {report.html}")
    if report.pdf is not None:
        print(f"report: {report.pdf} ({report.n_pages} pages)")
    return 0
