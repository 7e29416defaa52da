"""Shared CLI pieces of every fit: sampler arguments, the summary table, --out, exit code."""
from __future__ import annotations

import math

# what FitResult.save writes (feeler.calib.fit.FIT_FILES, without importing pandas for --help)
FIT_FILES = ("posterior.nc", "summary.csv", "verdict.json")

__all__ = ["FIT_FILES", "add_fit_arguments", "finish_fit", "print_summary", "round_inside", "format_estimate"]


def round_inside(mean: float, lo: float, hi: float, decimals: int) -> tuple[str, str, str]:
    """``mean``, ``lo``, ``hi`` as fixed-point strings with at most ``decimals`` decimals,
    fewer where needed so that the printed mean never lies outside the printed interval
    (a mean can sit outside an equal-tailed interval when most draws pile on one value,
    e.g. P(correct) = 1: 0.9996 [1.0000, 1.0000] prints as 1.000 [1.000, 1.000])."""
    vals = (float(mean), float(lo), float(hi))
    if not all(math.isfinite(v) for v in vals):
        return tuple(f"{v:.{max(decimals, 0)}f}" for v in vals)
    d = int(decimals)
    while d > -12:
        m, a, b = (round(v, d) for v in vals)
        if a <= m <= b:
            break
        d -= 1
    fmt = (lambda v: f"{round(v, d):.{d}f}") if d >= 0 else (lambda v: f"{round(v, d):.0f}")
    return fmt(vals[0]), fmt(vals[1]), fmt(vals[2])


def format_estimate(mean: float, lo: float, hi: float, decimals: int = 4, scale: float = 1.0) -> str:
    """``"m [lo, hi]"`` rounded by :func:`round_inside` after multiplying by ``scale``."""
    m, a, b = round_inside(mean * scale, lo * scale, hi * scale, decimals)
    return f"{m} [{a}, {b}]"


def _significant_decimals(row, digits: int = 5) -> int:
    top = max(abs(float(row["mean"])), abs(float(row["eti95_lb"])), abs(float(row["eti95_ub"])))
    return digits - 1 - math.floor(math.log10(top)) if top > 0 and math.isfinite(top) else digits


def _estimate_columns(row) -> tuple[str, str, str]:
    """Mean and interval of a summary row, 5 significant digits in fixed point; beyond
    10 decimals or 10 integer digits (a parameter in the wrong units, 1e-9 or 1e12) with
    one shared exponent instead of a hundred zeros."""
    d = _significant_decimals(row)
    vals = (float(row["mean"]), float(row["eti95_lb"]), float(row["eti95_ub"]))
    if -6 <= d <= 10:
        return round_inside(*vals, d)
    e = 4 - d                                       # the largest value's exponent
    return tuple(f"{v}e{e:+d}" for v in round_inside(*(v / 10.0 ** e for v in vals), 4))


def _without_rounding_noise(table, rel: float = 1e-12):
    """``table`` with every mean, sd and bound below ``rel`` times its quantity's scale (the
    largest mean or bound over the rows of one name, ``plate_mean_mm[0]`` and ``[1]`` alike) set to 0:
    a two-plate decoder pins its plates' heights exactly, and the plate at 0 printed its float
    rounding as -0.4632e-17 [-1.3878e-17, 0.5204e-17]."""
    import numpy as np

    out = table.copy()
    values = ["mean", "sd", "eti95_lb", "eti95_ub"]
    family = out["name"].str.split("[", n=1, regex=False).str[0]
    for _, rows in out.groupby(family, sort=False):
        block = rows[values].to_numpy(dtype=float)
        where = block[:, [0, 2, 3]]                   # the scale: where the values lie, not their spread
        where = np.abs(where[np.isfinite(where)])
        if where.size == 0 or where.max() == 0:
            continue
        tiny = np.isfinite(block) & (np.abs(block) < rel * where.max())
        out.loc[rows.index, values] = np.where(tiny, 0.0, block)
    return out


def add_fit_arguments(parser, *, draws: int | None = 1000, tune: int | None = 1000, chains: int | None = 4,
                      helps: dict | None = None) -> None:
    """--out, --force, --seed, --chains, --draws, --tune, --progress/--no-progress.

    ``chains``/``draws``/``tune`` None: the command picks a default per backend, and refuses
    a typed value its backend would not use (:func:`feeler.commands._checks.refuse_unused`).
    ``helps``: the --help text of ``chains``, ``draws`` or ``tune`` when the command's own
    (what each backend does with it)."""
    helps = helps or {}
    parser.add_argument("--out", default=None, metavar="DIR",
                        help="write posterior.nc, summary.csv and verdict.json into DIR")
    parser.add_argument("--force", action="store_true", help="overwrite an earlier fit in DIR")
    parser.add_argument("--seed", type=int, default=0, help="seed of the random generator (default 0)")
    from feeler.commands._checks import MAX_CHAINS, MAX_TOTAL_DRAWS, MAX_TUNE

    parser.add_argument("--chains", type=int, default=chains,
                        help=helps.get("chains", f"chains (default {chains or 'per backend'}, at most {MAX_CHAINS})"))
    parser.add_argument("--draws", type=int, default=draws,
                        help=helps.get("draws", f"kept draws per chain (default {draws or 'per backend'}; chains × "
                                                f"draws at most {MAX_TOTAL_DRAWS})"))
    parser.add_argument("--tune", type=int, default=tune,
                        help=helps.get("tune", f"warm-up steps per chain (default {tune or 'per backend'}, at most "
                                               f"{MAX_TUNE})"))
    parser.add_argument("--progress", action="store_true", default=None, help="always show progress bars")
    parser.add_argument("--no-progress", dest="progress", action="store_false", help="never show progress bars")
    parser.set_defaults(out_files=FIT_FILES)       # checked before the fit (feeler.cli)


def print_summary(result, *, skip_prefixes: tuple[str, ...] = ()) -> None:
    """The summary table, the priors and the verdict on stdout. A quantity the model fixes
    at every draw (two-mode's snap offset on a plate of step 0) shows R-hat "fixed": its
    R-hat is 0/0, and the verdict does not check it. A quantity without a finite draw (one
    plate: no gain, no offset) shows dashes, not NaN; the verdict names it."""
    import pandas as pd

    table = result.summary[~result.summary["name"].str.startswith(skip_prefixes)] if skip_prefixes \
        else result.summary
    cols = ["name", "mean", "sd", "eti95_lb", "eti95_ub", "r_hat", "ess_bulk", "ess_tail"]
    shown = table[cols].astype(object).copy()
    for i, row in _without_rounding_noise(table[cols]).iterrows():   # mean, interval: same rounding, mean inside
        shown.loc[i, ["mean", "eti95_lb", "eti95_ub"]] = _estimate_columns(row)
        shown.loc[i, "sd"] = f"{row['sd']:.3g}"
        if not math.isfinite(row["mean"]):             # no finite draw (the verdict names it): no numbers
            shown.loc[i, cols[1:]] = "—"
        elif row["sd"] == 0 and not math.isfinite(row["r_hat"]):      # the same at every draw: nothing to mix
            shown.loc[i, ["r_hat", "ess_bulk", "ess_tail"]] = ("fixed", "-", "-")
        else:
            shown.loc[i, ["r_hat", "ess_bulk", "ess_tail"]] = (f"{row['r_hat']:.4f}", f"{row['ess_bulk']:.0f}",
                                                               f"{row['ess_tail']:.0f}")
    with pd.option_context("display.width", 120, "display.max_rows", 200):
        print(shown.to_string(index=False))
    print("priors:")
    for name, text in result.priors.items():
        print(f"  {name}: {text}")
    print(f"backend {result.backend}, {result.seconds:.3f} s")
    print(verdict_text(result.verdict))


def verdict_text(verdict) -> str:
    """``verdict: ok``, or ``verdict: FAILED (N problem[s])`` and one indented line per problem."""
    if verdict.ok:
        return "verdict: ok"
    n = len(verdict.problems)
    return "\n".join([f"verdict: FAILED ({n} problem{'' if n == 1 else 's'})"] + [f"  {p}" for p in verdict.problems])


def finish_fit(result, args) -> int:
    """Print, save with --out, and return 0 (verdict ok) or 1 (failed)."""
    print_summary(result)
    if args.out:
        if getattr(args, "progress", None) is not False:
            import sys
            print(f"writing {args.out} ...", file=sys.stderr, flush=True)
        out = result.save(args.out, force=args.force)
        print(f"wrote {out / 'posterior.nc'}, {out / 'summary.csv'}, {out / 'verdict.json'}")
    return 0 if result.verdict.ok else 1
