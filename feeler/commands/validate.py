"""Validate the statistical models. Sub-commands:

  sbc   simulation-based calibration: draw parameters from a model's prior, simulate
        data, fit, and test that the rank of every true parameter among its posterior
        draws is uniform (chi-square and simultaneous ECDF band). Datasets fan out over
        dask.distributed: a LocalCluster (2 workers) by default, or an existing scheduler
        with --scheduler tcp://HOST:PORT; --scheduler serial runs in this process.
        matrix: K, the noise sds, C = K^-1 and cond(C) on the sensor-calibration design
        (exact posterior). neuron: the plate means and spreads ("growing" noise) at the
        four-plates design and window, and the derived a, h, decoded-height means and
        sds (exact posterior; the window's weights are a model-averaging device over
        decoders, not a parameter with a likelihood, so it is held at the scene's).

Writes ranks.csv (one row per dataset) and sbc.csv (p-values per parameter) with --out;
the exit status is 1 when a parameter fails (Bonferroni-corrected level 0.01).
"""
from __future__ import annotations

import argparse
import importlib

__all__ = ["NAME", "HELP", "register", "SBC_MODELS"]

NAME = "validate"
HELP = "simulation-based calibration of the models (validate sbc --model matrix)"

# model name -> "module:factory"; factory() returns picklable (simulate, fit) for run_sbc.
SBC_MODELS = {
    "matrix": "feeler.calib.matrix.sbc_model:matrix_sbc_problem",
    "neuron": "feeler.calib.neuron.sbc:neuron_sbc_problem",
}


# validate sbc --help: the docstring without its list header, and an example
_SBC_DOC = ("Simulation-based calibration:" + __doc__.split("simulation-based calibration:", 1)[1]
            .replace("\n        ", "\n") + "\nExample:\n    feeler validate sbc --model matrix --n 20 --out runs/sbc-matrix\n")


def register(parser) -> None:
    from feeler.commands._checks import MAX_SBC_N

    sub = parser.add_subparsers(title="validations", metavar="WHAT")
    sbc = sub.add_parser("sbc", help="simulation-based calibration of one model",
                         description=_SBC_DOC)
    sbc.add_argument("--model", choices=sorted(SBC_MODELS), required=True, help="which model")
    sbc.add_argument("--n", type=int, default=200,
                     help=f"simulated datasets, {MIN_SBC_N}-{MAX_SBC_N} (default 200; below {LOW_POWER_N} only a "
                          f"gross miscalibration shows)")
    sbc.add_argument("--draws", type=int, default=99, help="posterior draws per dataset for the ranks, 9-999 (default 99)")
    sbc.add_argument("--scheduler", default=None, metavar="ADDR",
                     help="tcp://HOST:PORT of a dask scheduler, or 'serial' (default: a LocalCluster)")
    sbc.add_argument("--seed", type=int, default=0, help="seed (default 0)")
    sbc.add_argument("--out", default=None, metavar="DIR", help="write ranks.csv and sbc.csv into DIR")
    sbc.set_defaults(out_files=("ranks.csv", "sbc.csv"))
    sbc.add_argument("--force", action="store_true", help="overwrite an earlier run in DIR")
    sbc.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None,
                     help="progress on stderr (default: a bar on a terminal, a line per dataset with the "
                          "time left otherwise; --no-progress: none)")
    sbc.set_defaults(run=run_sbc_command)


#: independent draws each SBC fit returns (``fit_matrix_draws``, ``fit_neuron_draws``); --draws thins them
FIT_DRAWS = 999

#: the fewest datasets a run takes (the help states the range: 10 to _checks.MAX_SBC_N)
MIN_SBC_N = 10

#: below this many datasets an "ok" says how little it covers: a uniformity test over 10-20
#: datasets has little power (SBC of 10 datasets printed "every parameter's ranks are uniform")
LOW_POWER_N = 100


def run_sbc_command(args) -> int:
    from feeler.errors import ArgumentError

    from feeler.commands._checks import MAX_SBC_N

    if args.n < MIN_SBC_N:                           # before the heavy imports (issue 16 item 3)
        raise ArgumentError("--n", args.n, f"{MIN_SBC_N} to {MAX_SBC_N} simulated datasets")
    if not 9 <= args.draws <= FIT_DRAWS:
        raise ArgumentError("--draws", args.draws, f"9 to {FIT_DRAWS} posterior draws per dataset (ranks 0..draws; "
                            f"each fit draws {FIT_DRAWS}, evenly thinned to --draws)")
    import pandas as pd

    from feeler.calib.sbc import run_sbc
    from feeler.rundir import prepare_out_dir

    module_name, factory = SBC_MODELS[args.model].split(":")
    simulate, fit = getattr(importlib.import_module(module_name), factory)()
    if args.out:
        prepare_out_dir(args.out, ("ranks.csv", "sbc.csv"), force=args.force)
    res = run_sbc(simulate, fit, n_datasets=args.n, seed=args.seed, n_draws=args.draws,
                  scheduler=args.scheduler, progress=args.progress)
    table = res.table()
    with pd.option_context("display.width", 120, "display.max_rows", 200):
        print(f"SBC of model {args.model}: {args.n} datasets, ranks among {args.draws} draws")
        print(table.to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    failed = res.failed()
    if args.out:
        out = prepare_out_dir(args.out, (), force=True)
        pd.DataFrame(res.ranks, columns=list(res.names)).to_csv(out / "ranks.csv", index_label="dataset")
        table.to_csv(out / "sbc.csv", index=False)
        print(f"wrote {out / 'ranks.csv'}, {out / 'sbc.csv'}")
    if failed:
        print(f"SBC FAILED for: {', '.join(failed)}")
        return 1
    # a uniformity test of a few datasets has little power: say what "ok" covers
    weak = (f"; with {args.n} datasets only a gross miscalibration shows (the default --n 200 for a real check)"
            if args.n < LOW_POWER_N else "")
    print(f"SBC ok: no parameter's ranks depart from uniform{weak}")
    return 0
