"""Run the demo: the paper's robot experiment on the shipped four-plates scene.

Simulates datasets-synthetic/four-plates.toml into OUT/four-plates/, runs the FA-I
neuron on every scan, prints a per-plate table (peak z mean ± sd, raw U_dot_y peak, the
ΔU_y jump, and the 2AFC proportion correct of each adjacent plate pair by peak z and by
raw U_dot_y), and writes figures like the paper's Figs 7-9 (PNG) and robot_table.json
into OUT. This is what `make demo` runs.
"""
from __future__ import annotations

__all__ = ["NAME", "HELP", "register"]

NAME = "demo"
HELP = "simulate four-plates, decode with the neuron, print the table, draw Figs 7-9"


def register(parser) -> None:
    parser.add_argument("--out", default="runs/demo", metavar="DIR", help="output directory (default runs/demo)")
    parser.add_argument("--force", action="store_true", help="overwrite results of an earlier demo in DIR")
    parser.add_argument("--scene", default=None, metavar="SCENE",
                        help="robot-scan scene to use instead of the shipped four-plates")
    parser.set_defaults(run=run)


def run(args) -> int:
    from feeler.demo import FIGURES, run_demo

    ctx = run_demo(args.out, force=args.force, scene_path=args.scene)
    print(f"figures: {', '.join(str(ctx['out'] / f) for f in FIGURES)}")
    return 0
