"""Discrimination of step heights by the calibrated robot (M3).

POSTERIOR is a directory written by `feeler calibrate neuron --out`. Responses to any step
height come from the scene's forward scan model (default: the shipped four-plates scene),
decoded by each posterior draw. Prints the 2AFC proportion correct for pairs of heights
(--pair LOW HIGH, repeatable; default the pairs of the four plates), the difference
threshold at 75 % around --reference (default 0.1 mm) with its Weber fraction, and the
PSE of the reference step between two scan speeds (--speeds REF TEST). All with 95 %
credible intervals. A failed posterior is refused unless --accept-failed.
"""
from __future__ import annotations

from feeler.commands._posterior_use import add_use_arguments, load_checked

__all__ = ["NAME", "HELP", "register", "run"]

NAME = "discriminate"
HELP = "2AFC discrimination probabilities, threshold, Weber fraction and speed PSE from a neuron posterior"


def register(parser) -> None:
    add_use_arguments(parser, n_draws=200, out_file="discrimination.json")
    parser.add_argument("--scene", default=None, help="robot-scan scene of the forward model (default four-plates)")
    parser.add_argument("--backend", choices=("forward",), default="forward",
                        help="forward: simulated touches decoded per posterior draw (the only one)")
    parser.add_argument("--pair", type=float, nargs=2, action="append", default=None, metavar=("LOW", "HIGH"),
                        help="step heights to compare, mm (repeatable)")
    parser.add_argument("--reference", type=float, default=0.1, help="reference step for the threshold, mm")
    parser.add_argument("--speeds", type=float, nargs=2, default=None, metavar=("REF", "TEST"),
                        help="scan speeds for the PSE, mm/s (default: the scene's and twice it)")
    parser.add_argument("--n-scans", type=int, default=400, help="touches simulated per height (default 400)")
    parser.set_defaults(run=run)


def run(args) -> int:
    from itertools import combinations

    from feeler.calib.neuron.discriminate import Discriminator
    from feeler.calib.neuron.synth import FOUR_PLATES
    from feeler.calib.progress import progress
    from feeler.rundir import prepare_out_dir, write_json
    from feeler.scene import load_scene

    result = load_checked(args)
    scene_path = args.scene or FOUR_PLATES
    scene = load_scene(scene_path)
    disc = Discriminator(result, scene_path=scene_path, n_scans=args.n_scans, n_draws=args.n_draws, seed=args.seed)
    pairs = args.pair or list(combinations(sorted(scene.surface.heights_mm), 2))
    rows = []
    print(f"{'low mm':>8} {'high mm':>8} {'P(correct)':>10}  95 % interval")
    for lo, hi in progress(pairs, desc="pairs"):
        p = disc.pc(lo, hi)
        rows.append({"low_mm": lo, "high_mm": hi, "pc": p.mean, "lo95": p.lo95, "hi95": p.hi95})
        print(f"{lo:8.4g} {hi:8.4g} {p.mean:10.4f}  [{p.lo95:.4f}, {p.hi95:.4f}]")
    th = disc.threshold(args.reference)
    d = th.delta75_mm
    print(f"threshold at 75 % around {args.reference:g} mm: {d.mean * 1e3:.2f} um [{d.lo95 * 1e3:.2f}, "
          f"{d.hi95 * 1e3:.2f}]; Weber fraction {th.weber.mean:.4f} [{th.weber.lo95:.4f}, {th.weber.hi95:.4f}]"
          + ("" if th.found == 1 else f" ({100 * (1 - th.found):.0f} % of draws never reach 75 %)"))
    v_ref, v_test = args.speeds or (scene.motion.speed_mm_s, 2 * scene.motion.speed_mm_s)
    pse = disc.pse(args.reference, v_ref, v_test)
    print(f"PSE of {args.reference:g} mm at {v_ref:g} mm/s when scanned at {v_test:g} mm/s: "
          f"{pse.mean:.4f} mm [{pse.lo95:.4f}, {pse.hi95:.4f}]")
    if args.out:
        out = prepare_out_dir(args.out, ("discrimination.json",), force=args.force)
        write_json(out / "discrimination.json", {
            "pairs": rows, "reference_mm": args.reference,
            "threshold_mm": {"mean": d.mean, "lo95": d.lo95, "hi95": d.hi95, "found": th.found},
            "weber": {"mean": th.weber.mean, "lo95": th.weber.lo95, "hi95": th.weber.hi95},
            "pse": {"speed_ref_mm_s": v_ref, "speed_test_mm_s": v_test, "mean_mm": pse.mean,
                    "lo95": pse.lo95, "hi95": pse.hi95}})
        print(f"wrote {out / 'discrimination.json'}")
    return 0
