"""Simulate a scene into a run directory.

Any shipped kind: robot-scan (four-plates), sensor-calibration (DIR/calibration.csv),
psychophysics-2afc (DIR/trials.csv), finger-steps (DIR/strain.csv); each also writes
DIR/scene.toml (a byte copy of SCENE) and DIR/truth.json. For a robot-scan scene
DIR/truth.json holds every true parameter (including each touch's press U_y0, tilt,
start offset and drift), and DIR/scans.csv (long format: scan_id, plate, step_mm,
speed_mm_s, t_s, x_mm, ux_mm, uy_mm, uz_mm), plus DIR/features.csv when the scene lists
"features" in its outputs. The result depends only on the scene file (its seed; --seed N
replaces it, and DIR/scene.toml then records N). Existing data are never overwritten
without --force; with it DIR holds this run only (see --force). The "wrote" line lists
the files this run wrote, nothing else in DIR. Progress on stderr: a
line per stage (and a bar over scans, frames or skin runs on a terminal; off a terminal
a line per skin run with the time left); --no-progress: none, only the "wrote" line on
stdout.

Example:
    feeler simulate datasets-synthetic/four-plates.toml --out runs/four-plates
"""
from __future__ import annotations

import argparse

__all__ = ["NAME", "HELP", "register"]

NAME = "simulate"
HELP = "simulate a scene (e.g. datasets-synthetic/four-plates.toml) into a run directory"


def register(parser) -> None:
    parser.add_argument("scene", metavar="SCENE", help="scene TOML file")
    parser.add_argument("--out", required=True, metavar="DIR", help="run directory to write")
    parser.add_argument("--force", action="store_true",
                        help="overwrite existing data in DIR, so that it holds this run only: the files of an "
                             "earlier simulation there that this one does not write (its calibration.csv, say), "
                             "the results of decode and classify on its scans (decisions.csv, classification.csv) "
                             "and an earlier report are removed, with a line saying so; other data or results of "
                             "names feeler reads (a fit, an acquisition, a measured calibration.csv) are refused "
                             "before any work, never deleted; files of other names (your notes) are left as they "
                             "were and named as not this run's")
    parser.add_argument("--seed", type=int, metavar="N",
                        help="root seed of the random draws (0 to 2**63-1) instead of the scene's own [scene] seed; "
                             "DIR/scene.toml records it, so the run is reproduced from that file "
                             "(finger-steps scenes draw nothing at random and refuse it)")
    parser.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None,
                        help="progress on stderr (default: a line per stage, and a bar on a terminal; "
                             "--no-progress: none)")
    parser.set_defaults(run=run)


def run(args) -> int:
    from feeler.scene import load_scene
    from feeler.simulate import run_simulation, written_files

    out = run_simulation(args.scene, args.out, force=args.force, seed=args.seed, progress=args.progress)
    print(f"wrote {out}: {', '.join(written_files(out, load_scene(args.scene)))}")     # its own files only
    return 0
