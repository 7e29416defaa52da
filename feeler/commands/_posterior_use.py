"""Shared CLI pieces of the commands that use a saved neuron posterior (classify, discriminate)."""
from __future__ import annotations

__all__ = ["add_use_arguments", "load_checked"]


def add_use_arguments(parser, *, n_draws: int, out_file: str,
                      seed_help: str = "seed of the subsample of posterior draws (default 0)") -> None:
    """POSTERIOR, --n-draws, --seed (``seed_help`` says what it seeds), --out, --force,
    --accept-failed, --progress/--no-progress."""
    parser.add_argument("posterior", metavar="POSTERIOR", help="directory of a `calibrate neuron --out` fit")
    parser.add_argument("--n-draws", type=int, default=n_draws, help=f"posterior draws used (default {n_draws})")
    parser.add_argument("--seed", type=int, default=0, help=seed_help)
    parser.add_argument("--out", default=None, metavar="DIR", help=f"write {out_file} into DIR")
    parser.add_argument("--force", action="store_true", help="overwrite an earlier result in DIR")
    parser.add_argument("--accept-failed", action="store_true", help="use a posterior that failed its diagnostics")
    parser.add_argument("--progress", action="store_true", default=None,
                        help="always show progress (default: bars on a terminal, lines otherwise)")
    parser.add_argument("--no-progress", dest="progress", action="store_false", help="no progress output")
    parser.set_defaults(out_files=(out_file,))     # checked before any work (feeler.cli)


def load_checked(args):
    """The saved fit of ``args.posterior``; CalibrationFailed unless ok or --accept-failed."""
    from feeler.calib.fit import load, require_ok
    from feeler.errors import ArgumentError, DataFileError

    if args.n_draws < 2:
        raise ArgumentError("--n-draws", args.n_draws, ">= 2")
    result = load(args.posterior)
    post = result.posterior["posterior"]
    if "length_mm" not in post.attrs or "tau_s" not in post.data_vars:      # M1, M4, finger route
        names = ", ".join(list(post.data_vars)[:4])
        raise DataFileError(args.posterior, f"a fit of {names}, not a neuron (M2) fit; POSTERIOR must be "
                                            f"the --out directory of `feeler calibrate neuron`")
    available = int(post.sizes.get("chain", 1) * post.sizes.get("draw", 1))
    if args.n_draws > available:                  # every draw is used: say so, and print the true count
        print(f"note: --n-draws {args.n_draws} is more than the fit's {available} posterior draws: all "
              f"{available} are used")
        args.n_draws = available
    return require_ok(result, accept_failed=args.accept_failed, what="neuron calibration")
