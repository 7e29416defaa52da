"""Calibrate many sensor elements at once: one M1 posterior per DATASET, fanned out over
dask.distributed.

Each DATASET is what `feeler calibrate sensor` takes (a directory with calibration.csv
and scene.toml). The fits run on a LocalCluster (2 worker processes on this machine) by
default, on an existing scheduler with --scheduler tcp://HOST:PORT, or in this process
with --scheduler serial. Element i uses seed SEED + i, so the results are identical
whichever way they are computed. OUT/<dataset name>/ receives each element's
posterior.nc, summary.csv and verdict.json; the closing table lists every verdict and
the exit status is 1 when any failed.
"""
from __future__ import annotations

from functools import partial
from pathlib import Path

__all__ = ["HELP", "register", "run", "fit_element"]

HELP = "posteriors of the force→displacement matrices of many sensor elements (dask)"


def register(parser) -> None:
    parser.add_argument("datasets", metavar="DATASET", nargs="+", help="calibration run directories")
    parser.add_argument("--out", required=True, metavar="DIR", help="write DIR/<dataset name>/ per element")
    parser.add_argument("--force", action="store_true", help="overwrite earlier fits in DIR")
    parser.add_argument("--seed", type=int, default=0, help="seed of element 0; element i uses SEED + i")
    parser.add_argument("--scheduler", default=None, metavar="ADDR",
                        help="tcp://HOST:PORT of a dask scheduler, or 'serial' (default: a LocalCluster)")
    parser.add_argument("--workers", type=int, default=2, help="LocalCluster worker processes (default 2)")
    parser.add_argument("--progress", action="store_true", default=None, help="always show progress bars")
    parser.add_argument("--no-progress", dest="progress", action="store_false", help="never show progress bars")
    parser.set_defaults(run=run)


def fit_element(index: int, *, datasets: tuple[str, ...], seed: int):
    """The exact M1 posterior of element ``index`` (picklable for dask workers)."""
    import warnings

    import numpy as np

    from feeler.calib.fit import DiagnosticWarning
    from feeler.calib.matrix import fit_matrix, read_calibration_csv
    from feeler.calib.matrix.data import DesignWarning
    from feeler.commands._calibrate_sensor import _locate, _prior

    csv, scene = _locate(Path(datasets[index]))
    data = read_calibration_csv(csv)
    prior, _, _ = _prior(_Defaults(), scene)
    with warnings.catch_warnings():                 # both are in the element's verdict, printed below the table;
        warnings.simplefilter("ignore", DiagnosticWarning)       # in a dask worker they would print raw, with
        warnings.simplefilter("ignore", DesignWarning)           # their source line (no one-line formatter there)
        return fit_matrix(data, prior, backend="exact", rng=np.random.default_rng(seed + index),
                          progress=False)


class _Defaults:
    """The per-element options of `calibrate sensor` at their defaults (prior from scene.toml)."""
    c0 = rel_sd = stage_sd_mm = None


def run(args) -> int:
    from feeler.calib.runner import map_seeds
    from feeler.errors import ArgumentError
    from feeler.rundir import prepare_out_dir

    names = [Path(d).resolve().name for d in args.datasets]
    if len(set(names)) != len(names):
        raise ArgumentError("DATASET", names, "dataset directories must have distinct names")
    out = prepare_out_dir(args.out, [f"{n}/verdict.json" for n in names], force=args.force)
    job = partial(fit_element, datasets=tuple(str(d) for d in args.datasets), seed=args.seed)
    results = map_seeds(job, range(len(names)), scheduler=args.scheduler, n_workers=args.workers,
                        desc="elements", progress_bar=args.progress)
    print(f"{'element':24s} {'verdict':8s} {'cond(C)':>8s}   C diagonal (mm/N)")
    for name, res in zip(names, results):
        res.save(out / name, force=args.force)
        s = res.summary.set_index("name")["mean"]
        diag = ", ".join(f"{s[f'C[{i},{i}]']:.4f}" for i in range(3))
        print(f"{name:24s} {'ok' if res.verdict.ok else 'FAILED':8s} {s['cond_C']:8.3f}   {diag}")
    for name, res in zip(names, results):               # why each failed: its first problem, and where the rest are
        if not res.verdict.ok:
            problems = res.verdict.problems
            more = f"and {len(problems) - 1} more: " if len(problems) > 1 else ""
            print(f"{name}: {problems[0]} ({more}{out / name / 'verdict.json'})")
    print(f"wrote {len(names)} posteriors under {out}")
    return 0 if all(r.verdict.ok for r in results) else 1
