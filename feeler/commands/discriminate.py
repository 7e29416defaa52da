"""Discrimination of step heights by the calibrated robot (M3).

POSTERIOR is a directory written by `feeler calibrate neuron --out`. Responses to any step
height come from the forward scan model of the scene the fit was trained on (recorded in
the fit; --scene overrides it, and a fit made from a bare CSV needs it), decoded by each
posterior draw. Prints the 2AFC proportion correct for pairs of heights (--pair LOW HIGH,
repeatable; default the pairs of the scene's plates), the difference threshold at 75 %
around --reference (default 0.1 mm) with its Weber fraction, and the PSE of the reference
step between two scan speeds (--speeds REF TEST). Of a pair, the touch with the larger
peak z is called higher: the neuron's response, as in the paper's 2AFC, with one decoder for
every touch (`classify` reads snapping and riding touches apart and can tell fresh pairs apart
more often). 95 % intervals include the posterior
and the Monte Carlo error of the --n-scans simulated touches (bootstrap per draw; "MC se"
is the latter alone; "-" when the touches of the two heights never overlap (or in under 2.5 %
of draws, with their share), where the
interval's far end is the bound from n disjoint pairs all correct, 0.025^(1/n)). The touches belong to the forward model and are seeded from the
scene's seed, so reruns with another --seed (posterior draws, resamples) agree within
their intervals; --touch-seed simulates another set of touches. A threshold that many
draws do not reach within the searched range is printed as a bound ("> 25.00 um") with
the fraction of draws. A failed posterior is refused unless --accept-failed.
"""
from __future__ import annotations

import math

from feeler.commands._posterior_use import add_use_arguments, load_checked

__all__ = ["NAME", "HELP", "register", "run", "threshold_text", "interval_json", "mcse_text"]

#: what P(correct) measures, printed with it: an outside audit read it against classify's pairs
RULE = ("2AFC rule: the touch whose peak z is larger is called higher (the paper's neuron response, one decoder "
        "for every touch); `classify`, which reads snapping and riding touches apart, can tell fresh pairs apart "
        "more often")
NAME = "discriminate"
HELP = "2AFC discrimination probabilities, threshold, Weber fraction and speed PSE from a neuron posterior"


def register(parser) -> None:
    add_use_arguments(parser, n_draws=200, out_file="discrimination.json",
                      seed_help="seed of the posterior draws and bootstrap resamples (default 0); the simulated "
                                "touches have --touch-seed")
    parser.add_argument("--scene", default=None, help="robot-scan scene of the forward model (default: the fit's)")
    parser.add_argument("--backend", choices=("forward",), default="forward",
                        help="forward: simulated touches decoded per posterior draw (the only one)")
    parser.add_argument("--pair", type=float, nargs=2, action="append", default=None, metavar=("LOW", "HIGH"),
                        help="step heights to compare, mm (repeatable)")
    parser.add_argument("--reference", type=float, default=0.1,
                        help="reference step for the threshold, mm (default 0.1)")
    parser.add_argument("--speeds", type=float, nargs=2, default=None, metavar=("REF", "TEST"),
                        help="scan speeds for the PSE, mm/s (default: the scene's and twice it)")
    parser.add_argument("--touch-seed", type=int, default=None,
                        help="root seed of the simulated touches (default: the scene's seed)")
    parser.add_argument("--n-scans", type=int, default=1000,
                        help="touches simulated per height (default 1000, 2-20000, and --n-draws × --n-scans at most "
                             "20000000; the Monte Carlo error shrinks as 1/sqrt)")
    parser.set_defaults(run=run)


def _num(v):
    import math
    return float(v) if math.isfinite(v) else None


def interval_json(iv, **extra) -> dict:
    """An :class:`Interval` as JSON (non-finite values as null)."""
    return {"mean": _num(iv.estimate), "lo95": _num(iv.lo95), "hi95": _num(iv.hi95), "mcse": _num(iv.mcse), **extra}


def mcse_text(p) -> str:
    """The "MC se" column of a pair: the standard error, or "-" with why there is none. The
    touches never overlap when every draw's P(correct) on them is 1 (or 0); when only a few
    draws' are not, the 2.5 % point is still 1: "never" would overstate it (0.9999983)."""
    import numpy as np

    if math.isfinite(p.mcse):
        return f"{p.mcse:.4f}"
    if np.all((p.draws >= 1.0) | (p.draws <= 0.0)):
        return "-  (touches never overlap)"
    share = np.mean((p.draws > 0.0) & (p.draws < 1.0))
    return f"-  (touches overlap in {100 * share:.1f} % of draws)" if share >= 0.001 else \
        "-  (touches overlap in under 0.1 % of draws)"


def share_text(u: float) -> str:
    """A share of draws in per cent, never rounded to 0 or 100 when it is neither."""
    pct = 100 * u
    if 0 < pct < 0.5:
        return "under 1"
    if 99.5 <= pct < 100:
        return "over 99"
    return f"{pct:.0f}"


def threshold_text(th, scale: float = 1e3, unit: str = "um") -> str:
    """The threshold as printed: an estimate with its interval, or a bound when draws
    do not reach 75 % within the searched range. A bound whose draws all reach 75 % on the
    touches as simulated says that it is their resamples (the simulation error) that do not."""
    from feeler.commands._fit_output import format_estimate

    d, top = th.delta75_mm, th.searched_mm * scale
    if th.found < 1:
        missing = f" ({share_text(1 - th.found)} % of draws do not reach 75 % within {top:.2f} {unit})"
    else:
        missing = (f" (every draw reaches 75 % within {top:.2f} {unit} on the touches simulated, but more than "
                   f"2.5 % do not once their simulation error is resampled)")
    if d.median == float("inf"):
        return f"> {top:.2f} {unit}{missing}"
    est = d.estimate
    if not th.is_bound:
        return f"{format_estimate(est, d.lo95, d.hi95, 2, scale)} {unit}" + ("" if th.found == 1 else missing)
    return f"{est * scale:.2f} [{d.lo95 * scale:.2f}, > {top:.2f}] {unit}{missing}"


#: posterior draws × touches per height: 100 times the default 200 × 1000 (the bootstrap's
#: indices alone take 16 bytes each, 320 MB here)
MAX_TOUCH_DRAWS = 20_000_000


def check_arguments(args) -> None:
    """One-line errors for heights, speeds and counts the forward model cannot simulate
    (outside a robot-scan scene's heights and speed), before the posterior is loaded or a
    touch simulated."""
    import math

    from feeler.errors import ArgumentError
    from feeler.commands._checks import MAX_N_SCANS
    from feeler.scene import param_bounds
    from feeler.scenes.robot_scan import MotionTable, Surface

    low, high = param_bounds(Surface, "heights_mm")
    top_speed = param_bounds(MotionTable, "speed_mm_s")[1]
    if not 2 <= args.n_scans <= MAX_N_SCANS:
        raise ArgumentError("--n-scans", args.n_scans, f"an integer from 2 to {MAX_N_SCANS}")
    for lo, hi in args.pair or ():
        if not all(math.isfinite(v) and low <= v <= high for v in (lo, hi)) or lo > hi:
            raise ArgumentError("--pair", f"{lo:g} {hi:g}", f"two step heights within {low:g}..{high:g} mm, the lower "
                                "first (LOW <= HIGH)")
    # the threshold and the PSE keep their comparison heights within the scenes' (Discriminator.search_top_mm)
    if not (math.isfinite(args.reference) and 0 < args.reference <= high / 2):
        raise ArgumentError("--reference", f"{args.reference:g}", f"a step height in (0, {high / 2:g}] mm")
    for v in args.speeds or ():
        if not (math.isfinite(v) and 0 < v <= top_speed):
            raise ArgumentError("--speeds", f"{v:g}", f"scan speeds in (0, {top_speed:g}] mm/s")


def run(args) -> int:
    from itertools import combinations

    from feeler.calib.neuron.discriminate import Discriminator
    from feeler.calib.neuron.scene_record import scene_note
    from feeler.calib.progress import progress, stage
    from feeler.commands._fit_output import format_estimate
    from feeler.errors import ArgumentError
    from feeler.rundir import prepare_out_dir, write_json
    from feeler.scene import load_scene

    check_arguments(args)
    result = load_checked(args)                   # --n-draws: at most the fit's draws
    if args.n_draws * args.n_scans > MAX_TOUCH_DRAWS:           # decoded touches and their bootstrap indices
        raise ArgumentError("--n-scans", args.n_scans, f"at most {MAX_TOUCH_DRAWS // args.n_draws} with "
                            f"{args.n_draws} posterior draws (--n-draws × --n-scans at most {MAX_TOUCH_DRAWS}: "
                            f"every draw decodes every touch, and they must fit in memory)")
    disc = Discriminator(result, scene_path=args.scene, n_scans=args.n_scans, n_draws=args.n_draws, seed=args.seed,
                         touch_seed=args.touch_seed)
    scene = load_scene(disc.scene_path)
    print(f"forward model: {args.scene or 'the scene recorded in the fit'} ({scene.surface.heights_mm} mm plates), "
          f"{args.n_scans} touches per height, {disc.a.size} posterior draws")
    print(RULE)
    pairs = args.pair or list(combinations(sorted(scene.surface.heights_mm), 2))
    outside = [n for n in (disc.outside_note(args.reference),
                           disc.outside_note([v for pair in pairs for v in pair], option="--pair")) if n]
    notes = [n for n in (disc.note, scene_note(result, args.scene)) if n] + outside
    for note in notes:
        print(note)
    rows = []
    print(f"{'low mm':>8} {'high mm':>8}  P(correct) [95 % interval]   MC se")
    for lo, hi in progress(pairs, desc="2AFC pairs", enabled=args.progress, lines=True):
        p = disc.pc(lo, hi)
        rows.append({"low_mm": lo, "high_mm": hi, "pc": p.estimate, "lo95": p.lo95, "hi95": p.hi95, "mcse": p.mcse})
        mcse = mcse_text(p)
        print(f"{lo:8.4g} {hi:8.4g}  {format_estimate(p.estimate, p.lo95, p.hi95, 4):28s} {mcse}")
    stage(f"difference threshold at 75 % around {args.reference:g} mm", args.progress)
    th = disc.threshold(args.reference)
    w = th.weber
    weber = (f"> {th.searched_mm / args.reference:.4f}" if w.median == float("inf") else
             format_estimate(w.estimate, w.lo95, w.hi95, 4) if not th.is_bound else
             f"{w.estimate:.4f} [{w.lo95:.4f}, > {th.searched_mm / args.reference:.4f}]")
    print(f"threshold at 75 % around {args.reference:g} mm: {threshold_text(th)}; Weber fraction {weber}")
    v_ref, v_test = args.speeds or (scene.motion.speed_mm_s, 2 * scene.motion.speed_mm_s)
    stage(f"PSE of {args.reference:g} mm between {v_ref:g} and {v_test:g} mm/s", args.progress)
    pse = disc.pse(args.reference, v_ref, v_test)
    print(f"PSE of {args.reference:g} mm at {v_ref:g} mm/s when scanned at {v_test:g} mm/s: "
          + (f"{format_estimate(pse.estimate, pse.lo95, pse.hi95, 4)} mm" if pse.found == 1 else
             "outside the searched {:g}-{:g} mm for {:.0f} % of draws".format(*disc.pse_range_mm(args.reference),
                                                                              100 * (1 - pse.found))))
    if args.out:
        out = prepare_out_dir(args.out, ("discrimination.json",), force=args.force)
        d = th.delta75_mm
        est = d.estimate
        bound = th.is_bound
        write_json(out / "discrimination.json", {
            "pairs": [{k: (_num(v) if isinstance(v, float) else v) for k, v in r.items()} for r in rows],
            "reference_mm": args.reference, "n_scans": args.n_scans, "n_draws": int(disc.a.size),
            "scene": str(args.scene or "recorded in the fit"),
            # what the command printed before its table (the report shows them), and whether a height
            # it was asked about lies outside the trained plates (the figures then extrapolate)
            "notes": notes, "extrapolated": bool(outside),
            "posterior_verdict": result.verdict.as_dict(),     # failed, with --accept-failed: said here too
            # a threshold no draw's median reaches is a bound, "> searched" (as the report reads it),
            # not a zero-width interval at the top of the search
            "threshold_mm": {"mean": f"> {th.searched_mm:g}" if _num(est) is None else _num(est),
                             "lo95": _num(d.lo95), "hi95": th.searched_mm if bound else _num(d.hi95), "found": th.found,
                             "median": _num(d.median), "mcse": _num(d.mcse), "searched_mm": th.searched_mm,
                             "hi95_is_bound": bound, "estimate_is_bound": d.median == float("inf")},
            "weber": interval_json(w, median=_num(w.median), hi95_is_bound=bound) | {"mean": _num(w.estimate)},
            "curve": th.curve,          # the curve the threshold was read from (the report draws it)
            "pse": {"speed_ref_mm_s": v_ref, "speed_test_mm_s": v_test, "mean_mm": _num(pse.estimate),
                    "lo95": _num(pse.lo95), "hi95": _num(pse.hi95), "mcse": _num(pse.mcse), "found": pse.found}})
        print(f"wrote {out / 'discrimination.json'}")
    return 0
