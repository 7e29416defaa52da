"""Finger skin mechanics: the L0/L1/L2 ladder study and the paper's Figs 3–6.

  feeler skin ladder [--out DIR] [--small]
      L2 mesh-convergence study (peak step strain must change < 1 % between the two
      finest meshes) and the trade table: seconds per slide (setup apart) and the error
      of the peak strain rate against converged L2 for L0, L1, L2. Writes
      convergence.csv, trade.csv, ladder.json and ladder.png.
  feeler skin figures SCENE --out DIR [--level l0|l1|l2] [--force]
      Figs 3–6 of the paper for a finger-steps scene (fig3_strain.png …
      fig6_accepted.png), with fig5_peaks.csv, fig6_accepted.csv and figures.json.

Example:
    feeler skin figures datasets-synthetic/finger-steps.toml --out runs/finger-figs
"""
from __future__ import annotations

import sys

__all__ = ["NAME", "HELP", "register"]

NAME = "skin"
HELP = "finger skin ladder study (L0/L1/L2) and the paper's Figs 3-6"


def register(parser) -> None:
    sub = parser.add_subparsers(title="skin commands", metavar="WHAT")
    lad = sub.add_parser("ladder", help="mesh convergence and the L0/L1/L2 trade table",
                         description="L2 mesh convergence and the trade between the skin fidelities L0, L1 and L2: "
                                     "seconds per slide against the error of the peak strain rate to converged L2. "
                                     "Writes convergence.csv, trade.csv, ladder.json and ladder.png into --out "
                                     "(default runs/skin-ladder). Exit status 1 when the full study misses a "
                                     "goal (peak step strain changing < 1 % between the two finest meshes, L1 "
                                     "100x faster than L2 within 10 % error, L0 10^4x faster); --small reports "
                                     "them without judging them. "
                                     "Example: feeler skin ladder --small --out runs/ladder")
    lad.add_argument("--out", default="runs/skin-ladder", metavar="DIR",
                     help="output directory (default runs/skin-ladder)")
    lad.add_argument("--small", action="store_true", help="coarse meshes and time steps (a quick check)")
    lad.add_argument("--force", action="store_true", help="overwrite existing results in DIR")
    _progress_flag(lad)
    lad.set_defaults(run=run_ladder)
    fig = sub.add_parser("figures", help="the paper's Figs 3-6 for a finger-steps scene",
                         description="The paper's Figs 3-6 for a finger-steps scene: strain at the corpuscle, "
                                     "normalised pulse density, peak against step height, accepted against presented "
                                     "height over the scene's tau sweep (PNGs, with fig5_peaks.csv, fig6_accepted.csv, "
                                     "figures.json). Example: feeler skin figures "
                                     "datasets-synthetic/finger-steps.toml --out runs/finger-figs")
    fig.add_argument("scene", metavar="SCENE", help="finger-steps scene TOML")
    fig.add_argument("--out", required=True, metavar="DIR", help="output directory")
    fig.add_argument("--level", choices=("l0", "l1", "l2"), help="override the scene's skin level")
    fig.add_argument("--force", action="store_true", help="overwrite existing results in DIR")
    _progress_flag(fig)
    fig.set_defaults(run=run_figures)


def _progress_flag(parser) -> None:
    import argparse

    parser.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None,
                        help="progress on stderr (default: a line per stage, and a bar on a terminal or a line "
                             "per mesh or run otherwise; --no-progress: none)")


def run_ladder(args) -> int:
    from feeler.skin.study import ladder_files, run_ladder_study, unmet_goals

    from feeler.rundir import prepare_out_dir
    out = prepare_out_dir(args.out, ladder_files(), force=args.force)
    if args.progress is not False:                      # what it is doing: stderr, as every command's progress
        print(f"skin ladder ({'small' if args.small else 'full'} study) into {out} ...", file=sys.stderr, flush=True)
    summary = run_ladder_study(out, small=args.small, progress=args.progress)
    for line in summary["lines"]:
        print(line)
    print(f"wrote {', '.join(str(out / f) for f in ladder_files())}")
    missed = unmet_goals(summary)
    if missed:
        print(f"feeler: failed: the skin ladder misses its goal(s): {'; '.join(missed)} "
              f"(the results are kept in {out})", file=sys.stderr)
        return 1
    return 0


def run_figures(args) -> int:
    from feeler.errors import SceneError
    from feeler.scene import load_scene
    from feeler.skin.study import figure_files, write_figures

    scene = load_scene(args.scene)
    if scene.scene.kind != "finger-steps":
        raise SceneError(args.scene, "scene.kind", f"{scene.scene.kind!r}: skin figures need a finger-steps scene")
    from feeler.rundir import prepare_out_dir
    out = prepare_out_dir(args.out, figure_files(), force=args.force)
    for line in write_figures(scene, out, level=args.level, progress=args.progress):
        print(line)
    print(f"wrote {', '.join(str(out / f) for f in figure_files())}")
    return 0
