"""Classify new plate scans with a calibrated neuron (M2 posterior).

POSTERIOR is a directory written by `feeler calibrate neuron --out`; SCANS a run directory
or scans.csv (strain uses the posterior's representative length). For each scan: the
probability of every training plate and the decoded step height with its 90 % interval
(inverting each plate's predictive band: at any true step the interval covers it 90 % of
the time), integrating over the posterior. A posterior that failed its diagnostics is refused unless
--accept-failed. --out DIR writes classification.csv.
"""
from __future__ import annotations

from feeler.commands._posterior_use import add_use_arguments, load_checked

__all__ = ["NAME", "HELP", "register", "run"]

NAME = "classify"
HELP = "plate probabilities and decoded step heights of new scans, from a neuron posterior"


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

    from feeler.calib.neuron.classify import classify
    from feeler.datasets import read_scans
    from feeler.rundir import prepare_out_dir

    result = load_checked(args)
    path = Path(args.scans)
    scans = read_scans(path / "scans.csv" if path.is_dir() else path)
    length = float(result.posterior["posterior"].attrs["length_mm"])
    from feeler.calib.neuron.data import shared_times
    from feeler.datasets import strain
    c = classify(result, strain(scans.uy_mm, length), shared_times(scans.t_s), rng=np.random.default_rng(args.seed),
                 n_draws=args.n_draws)
    table = pd.DataFrame({"scan_id": scans.scan_id, "step_mm": scans.step_mm, "plate_mm": c.plate_mm,
                          **{f"p_{v:g}mm": c.prob[:, i] for i, v in enumerate(c.plates_mm)},
                          "height_mm": c.height_mm, "lo90_mm": c.lo90_mm, "hi90_mm": c.hi90_mm})
    with pd.option_context("display.width", 160, "display.max_rows", 60):
        print(table.to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    hit = np.isclose(c.plate_mm, scans.step_mm)
    inside = (scans.step_mm >= c.lo90_mm) & (scans.step_mm <= c.hi90_mm)
    print(f"{hit.mean() * 100:.1f} % classified as their labelled plate; "
          f"{inside.mean() * 100:.1f} % of labels inside their 90 % interval")
    if args.out:
        out = prepare_out_dir(args.out, ("classification.csv",), force=args.force)
        table.to_csv(out / "classification.csv", index=False)
        print(f"wrote {out / 'classification.csv'}")
    return 0
