"""Calibrate many sensor elements at once: one M1 posterior per DATASET, fanned out over
dask.distributed.

Each DATASET is what `feeler calibrate sensor` takes (a directory with calibration.csv
and scene.toml). The fits run on a LocalCluster (2 worker processes on this machine) by
default, on an existing scheduler with --scheduler tcp://HOST:PORT, or in this process
with --scheduler serial. Element i uses seed SEED + i, so the results are identical
whichever way they are computed. OUT/<dataset name>/ receives each element's
posterior.nc, summary.csv and verdict.json; the closing table lists every verdict and
the exit status is 1 when any failed.

Every DATASET is read and its prior built before the first fit starts: a missing path, a
bad calibration.csv or a dataset without its nominal C0 (scene.toml) stops the command
with one line naming it (exit 2) before any work. An element that still raises during its
fit (a file changed meanwhile, a bug) is named in one line below the table; the elements
that finished are written all the same (exit 2 for bad input, else 1). Each element is
written as it finishes, so a Ctrl-C keeps the finished ones, and a dask worker that dies
loses only the elements it held: the others run on and are written before the error
(tests/calib/test_runner.py kills a worker under map_seeds). --resume then fits only the
elements not yet written (an element's verdict.json, written last, marks it complete).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from pathlib import Path

__all__ = ["HELP", "register", "run", "fit_element", "element_name"]

HELP = "posteriors of the force→displacement matrices of many sensor elements (dask)"


def register(parser) -> None:
    parser.add_argument("datasets", metavar="DATASET", nargs="+",
                        help="calibration run directories (or the calibration.csv in each)")
    parser.add_argument("--out", required=True, metavar="DIR", help="write DIR/<dataset name>/ per element")
    parser.add_argument("--force", action="store_true", help="overwrite earlier fits in DIR")
    parser.add_argument("--resume", action="store_true",
                        help="keep the elements already written in DIR (after a Ctrl-C or a lost worker) and fit "
                             "the others; the table lists all")
    parser.add_argument("--seed", type=int, default=0, help="seed of element 0; element i uses SEED + i")
    parser.add_argument("--scheduler", default=None, metavar="ADDR",
                        help="tcp://HOST:PORT of a dask scheduler, or 'serial' (default: a LocalCluster)")
    parser.add_argument("--workers", type=int, default=None,
                        help="LocalCluster worker processes (default 2; at most this machine's CPUs; not with "
                             "--scheduler, whose workers are its own)")
    parser.add_argument("--progress", action="store_true", default=None, help="always show progress bars")
    parser.add_argument("--no-progress", dest="progress", action="store_false", help="never show progress bars")
    parser.set_defaults(run=run)


def fit_element(index: int, *, datasets: tuple[str, ...], seed: int):
    """The exact M1 posterior of element ``index`` (picklable for dask workers)."""
    import warnings

    import numpy as np

    from feeler.calib.fit import DiagnosticWarning
    from feeler.calib.matrix import fit_matrix
    from feeler.calib.matrix.data import DesignWarning

    data, prior = _read_element(datasets[index])
    with warnings.catch_warnings():                 # both are in the element's verdict, printed below the table;
        warnings.simplefilter("ignore", DiagnosticWarning)       # in a dask worker they would print raw, with
        warnings.simplefilter("ignore", DesignWarning)           # their source line (no one-line formatter there)
        return fit_matrix(data, prior, backend="exact", rng=np.random.default_rng(seed + index),
                          progress=False)


@dataclass(frozen=True)
class ElementError:
    """What an element's fit raised, in place of its result (picklable, whatever the exception)."""
    message: str
    bad_input: bool            # an InputError: the CLI's 'feeler: error:' (exit 2); else 'feeler: failed:' (exit 1)


def _fit_or_error(index: int, *, datasets: tuple[str, ...], seed: int):
    """:func:`fit_element`, or an :class:`ElementError` when it raises: one element's exception
    no longer takes the finished ones with it (map_seeds re-raised it and nothing was written)."""
    from feeler.errors import FeelerError, InputError

    try:
        return fit_element(index, datasets=datasets, seed=seed)
    except Exception as exc:                        # noqa: BLE001 - reported below the table, with its kind
        text = str(exc) if isinstance(exc, FeelerError) else f"{exc.__class__.__name__}: {exc}"
        return ElementError(" ".join(text.split()), isinstance(exc, InputError))


def element_name(dataset: str) -> str:
    """The name of an element's directory under --out: its dataset directory's name, also when
    DATASET is the calibration.csv in it (OUT/calibration.csv/ was made for it)."""
    path = Path(dataset).resolve()
    return path.parent.name if path.is_file() else path.name


def _read_element(dataset: str):
    """The dataset's calibration data and prior, as `calibrate sensor` reads them at its defaults.

    Raises:
        InputError: a missing path or file, a bad calibration.csv, no scene.toml (this command
            has no --c0) or one that is not a sensor-calibration scene; one line naming the file.
    """
    from feeler.calib.matrix import read_calibration_csv
    from feeler.commands._calibrate_sensor import _locate, _prior
    from feeler.errors import DataFileError

    path = Path(dataset)
    if not path.exists():
        raise DataFileError(path, "no such dataset (a directory with calibration.csv and scene.toml)")
    csv, scene = _locate(path)
    data = read_calibration_csv(csv)
    if scene is None:
        raise DataFileError(csv.with_name("scene.toml"), "no such file: `calibrate sensors` takes each element's "
                                                         "nominal C0 from the scene.toml beside its calibration.csv "
                                                         "(a sensor-calibration scene, as `feeler simulate` writes)")
    prior, _, _ = _prior(_Defaults(), scene)
    return data, prior


def _check_datasets(datasets) -> None:
    """Read every dataset and build its prior before any fit: all problems at once, in one line.

    Raises:
        InputError: the first problem, followed by how many other datasets have problems and which.
    """
    from feeler.errors import InputError

    problems = []
    for d in datasets:
        try:
            _read_element(d)
        except InputError as exc:
            problems.append((d, exc))
    if not problems:
        return
    first = problems[0][1]
    if len(problems) == 1:
        raise first
    others = ", ".join(str(d) for d, _ in problems[1:])
    raise InputError(f"{first} (and {len(problems) - 1} more bad DATASET{'s' if len(problems) > 2 else ''}: "
                     f"{others}; nothing was fitted)") from None


class _Defaults:
    """The per-element options of `calibrate sensor` at their defaults (prior from scene.toml)."""
    c0 = rel_sd = stage_sd_mm = None


def run(args) -> int:
    import sys

    from feeler.calib.fit import load
    from feeler.calib.runner import map_seeds
    from feeler.commands._checks import refuse_unused
    from feeler.errors import ArgumentError, OverwriteError
    from feeler.rundir import prepare_out_dir

    names = [element_name(d) for d in args.datasets]
    if len(set(names)) != len(names):
        raise ArgumentError("DATASET", names, "dataset directories must have distinct names")
    if args.resume and args.force:
        raise ArgumentError("--resume/--force", True, "one of them: --resume keeps the written elements, "
                            "--force refits them")
    refuse_unused(args, {"workers": 2}, used=args.scheduler is None,
                  needs=lambda name: "needs a LocalCluster on this machine (no --scheduler): with --scheduler "
                                     + ("serial the fits run in this process" if args.scheduler == "serial" else
                                        f"{args.scheduler} the scheduler's own workers run them"))
    _check_datasets(args.datasets)
    written = [i for i, n in enumerate(names) if (Path(args.out) / n / "verdict.json").is_file()] \
        if args.resume else []
    try:
        out = prepare_out_dir(args.out, [f"{n}/verdict.json" for n in names], force=args.force or args.resume)
    except OverwriteError as exc:
        raise OverwriteError(exc.path, "pass --resume to fit only the elements not yet written, or --force to "
                                       "refit them all") from None
    kept = {i: load(out / names[i]) for i in written}
    if kept:
        print(f"--resume: {len(kept)} of {len(names)} element(s) already written under {out}, kept; fitting "
              f"{len(names) - len(kept)}", file=sys.stderr)
    job = partial(_fit_or_error, datasets=tuple(str(d) for d in args.datasets), seed=args.seed)
    todo = [i for i in range(len(names)) if i not in kept]
    saved = []

    def keep(k: int, res) -> None:             # each element written as it finishes, not after the last
        if not isinstance(res, ElementError):
            res.save(out / names[todo[k]], force=args.force)
            saved.append(names[todo[k]])

    try:
        fitted = map_seeds(job, todo, scheduler=args.scheduler, n_workers=args.workers,
                           desc="elements", progress_bar=args.progress, on_result=keep) if todo else []
    except BaseException:                      # a worker died, or Ctrl-C: say what is kept, then stop as before
        if saved:
            print(f"kept {len(saved)} finished posterior(s) under {out}: {', '.join(saved)}; run the same command "
                  f"with --resume to fit the others", file=sys.stderr)
        raise
    by_index = {**kept, **dict(zip(todo, fitted))}
    results = [by_index[i] for i in range(len(names))]
    done = [(name, res) for name, res in zip(names, results) if not isinstance(res, ElementError)]
    errors = [(name, res) for name, res in zip(names, results) if isinstance(res, ElementError)]
    print(f"{'element':24s} {'verdict':8s} {'cond(C)':>8s}   C diagonal (mm/N)")
    for name, res in zip(names, results):
        if isinstance(res, ElementError):
            print(f"{name:24s} {'ERROR':8s} {'-':>8s}   -")
            continue
        s = res.summary.set_index("name")["mean"]
        diag = ", ".join(f"{s[f'C[{i},{i}]']:.4f}" for i in range(3))
        print(f"{name:24s} {'ok' if res.verdict.ok else 'FAILED':8s} {s['cond_C']:8.3f}   {diag}")
    for name, res in done:                              # why each failed: its first problem, and where the rest are
        if not res.verdict.ok:
            problems = res.verdict.problems
            more = f"and {len(problems) - 1} more: " if len(problems) > 1 else ""
            print(f"{name}: {problems[0]} ({more}{out / name / 'verdict.json'})")
    kept_too = f" ({len(kept)} kept from the earlier run)" if kept else ""
    print(f"wrote {len(saved)} posterior{'' if len(saved) == 1 else 's'} under {out}{kept_too}")
    for name, err in errors:                            # one line each, as the CLI prints an error
        kind = "error" if err.bad_input else "failed"
        print(f"feeler: {kind}: element {name}: {err.message} (not fitted; nothing written for it)",
              file=sys.stderr)
    if errors:
        return 2 if any(err.bad_input for _, err in errors) else 1
    return 0 if all(r.verdict.ok for _, r in done) else 1
