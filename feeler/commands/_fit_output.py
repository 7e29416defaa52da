"""Shared CLI pieces of every fit: sampler arguments, the summary table, --out, exit code."""
from __future__ import annotations

__all__ = ["add_fit_arguments", "finish_fit", "print_summary"]


def add_fit_arguments(parser, *, draws: int | None = 1000, tune: int | None = 1000) -> None:
    """--out, --force, --seed, --chains, --draws, --tune, --progress/--no-progress.

    ``draws``/``tune`` None: the command picks a default per backend."""
    parser.add_argument("--out", default=None, metavar="DIR",
                        help="write posterior.nc, summary.csv and verdict.json into DIR")
    parser.add_argument("--force", action="store_true", help="overwrite an earlier fit in DIR")
    parser.add_argument("--seed", type=int, default=0, help="seed of the random generator (default 0)")
    parser.add_argument("--chains", type=int, default=4, help="chains (default 4)")
    parser.add_argument("--draws", type=int, default=draws,
                        help=f"kept draws per chain (default {draws or 'per backend'})")
    parser.add_argument("--tune", type=int, default=tune,
                        help=f"warm-up steps per chain (default {tune or 'per backend'})")
    parser.add_argument("--progress", action="store_true", default=None, help="always show progress bars")
    parser.add_argument("--no-progress", dest="progress", action="store_false", help="never show progress bars")


def print_summary(result, *, skip_prefixes: tuple[str, ...] = ()) -> None:
    """The summary table, the priors and the verdict on stdout."""
    import pandas as pd

    table = result.summary[~result.summary["name"].str.startswith(skip_prefixes)] if skip_prefixes \
        else result.summary
    cols = ["name", "mean", "sd", "eti95_lb", "eti95_ub", "r_hat", "ess_bulk", "ess_tail"]
    with pd.option_context("display.width", 120, "display.max_rows", 200):
        print(table[cols].to_string(index=False, float_format=lambda v: f"{v:.5g}"))
    print("priors:")
    for name, text in result.priors.items():
        print(f"  {name}: {text}")
    print(f"backend {result.backend}, {result.seconds:.3f} s")
    if result.verdict.ok:
        print("verdict: ok")
    else:
        print(f"verdict: FAILED ({len(result.verdict.problems)} problems)")
        for p in result.verdict.problems:
            print(f"  {p}")


def finish_fit(result, args) -> int:
    """Print, save with --out, and return 0 (verdict ok) or 1 (failed)."""
    print_summary(result)
    if args.out:
        out = result.save(args.out, force=args.force)
        print(f"wrote {out / 'posterior.nc'}, {out / 'summary.csv'}, {out / 'verdict.json'}")
    return 0 if result.verdict.ok else 1
