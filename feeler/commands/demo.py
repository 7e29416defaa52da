"""Run the demo: a whole calibration campaign on the shipped synthetic scenes.

This is what `make demo` runs. Stages, each with its progress line:
  1-4  simulate datasets-synthetic/four-plates.toml into OUT/four-plates/ (a --scene file
       into OUT/<its name without .toml>/), run the FA-I neuron on every scan, print the
       per-plate table (peak z, raw U_dot_y peak, the ΔU_y jump, 2AFC proportion correct
       of adjacent plates) and draw Figs 7-9;
  5    simulate the sensor-calibration campaign and fit the force→displacement matrix
       (M1, exact conjugate posterior) into OUT/m1/;
  6    fit the neuron's (a, tau, h, sigma) on the four plates (M2, exact grid) into OUT/m2/;
  7    classify fresh held-out scans with confidence (OUT/classify/);
  8    the robot's discrimination: 2AFC table, difference threshold, Weber fraction, PSE;
  9    simulate the SYNTHETIC human 2AFC data and fit psychometric functions (M4);
  10   infer tau and the decision noise through the finger chain;
  11   simulate the finger-steps scene (strain histories for the paper's Figs 3-6);
  12   speed/accuracy: copy the tables of the last `make bench`, and measure small
       versions of what they do not cover (skin ladder, calibration backends, sensor
       fidelities), labelled as measured during the demo;
  13   write OUT/report.html, OUT/report.pdf and OUT/report-manifest.json.
Results go to stdout; each stage's progress to stderr (--no-progress: none). Every
stage's full output is kept in OUT/logs/. A closing table lists each stage's wall
and CPU time and verdict. A stage that fails (a fit whose verdict fails, with --scene a
scene the fits cannot pin down) is named with its log; the stages that need its results
are skipped, the others still run and the report shows them all with the failed verdict;
the demo then exits with that stage's status (1 for a failed verdict).
Ctrl-C stops the demo once the running stage has stopped: one line names the stages that
finished (their outputs are kept) and says that no report was built; exit 130.
"""
from __future__ import annotations

import argparse

__all__ = ["NAME", "HELP", "register"]

NAME = "demo"
HELP = "the main job: simulate, calibrate, classify, discriminate, fit humans, write the report"


def register(parser) -> None:
    parser.add_argument("--out", default="runs/demo", metavar="DIR", help="output directory (default runs/demo)")
    parser.add_argument("--force", action="store_true", help="overwrite results of an earlier demo in DIR")
    parser.add_argument("--scene", default=None, metavar="SCENE",
                        help="robot-scan scene to use instead of the shipped four-plates")
    parser.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None,
                        help="on stderr, a line before each stage with the time so far and the stage's own "
                             "progress (default; --no-progress: none, stdout keeps the results)")
    parser.set_defaults(run=run)


def run(args) -> int:
    import json

    import sys

    from feeler.demo import FIGURES, STAGES, run_demo
    from feeler.demo.campaign import NEEDS, DemoIncomplete, DemoInterrupted

    incomplete = None
    try:
        ctx = run_demo(args.out, force=args.force, scene_path=args.scene, progress=args.progress,
                       stage_echo=lambda line: print(line, file=sys.stderr, flush=True))   # results stay on stdout
    except DemoIncomplete as exc:                  # the closing table still; the exit status says it failed
        incomplete, ctx = exc, exc.ctx
    except DemoInterrupted as exc:                 # no closing table: one line says what is kept
        print(f"feeler: {exc.message()}", file=sys.stderr, flush=True)
        return exc.code
    out = ctx["out"]
    print("\nsummary" + "-" * 62)
    print(f"{'stage':20s} {'seconds':>8s} {'cpu s':>7s}   result")
    skipped = incomplete.skipped if incomplete else []
    for name in [n for n, _ in STAGES if n in ctx["seconds"] or n in skipped]:
        if name in skipped:
            print(f"{name:20s} {'-':>8s} {'-':>7s}   skipped: it needs {NEEDS[name]}, which failed")
            continue
        sec = ctx["seconds"][name]
        print(f"{name:20s} {sec:8.1f} {ctx['cpu_seconds'][name]:7.1f}   {_result(out, name, json, incomplete)}")
    print(f"{'total':20s} {sum(ctx['seconds'].values()):8.1f} {sum(ctx['cpu_seconds'].values()):7.1f}")
    print(f"figures: {', '.join(str(out / f) for f in FIGURES)}")
    if "report" in ctx:
        print(f"report:  {ctx['report'].html}")
    if incomplete is not None:
        print(f"feeler: failed: {incomplete}", file=sys.stderr)
        return incomplete.code
    return 0


_FITS = {"calibrate sensor": "m1", "calibrate neuron": "m2", "psychophysics": "m4", "finger route": "finger-route"}


def _result(out, stage: str, json, incomplete=None) -> str:
    """One line per stage for the closing table, read back from the run's files."""
    if incomplete is not None and stage in incomplete.failed and stage not in _FITS:
        return f"FAILED (exit {incomplete.failed[stage].code}; see {incomplete.failed[stage].log})"
    if stage in _FITS:
        path = out / _FITS[stage] / "verdict.json"
        if path.is_file():
            v = json.loads(path.read_text())
            return f"verdict {'ok' if v['ok'] else 'FAILED: ' + '; '.join(v['problems'])} ({path.parent.name}/)"
    if stage == "discriminate" and (out / "discriminate" / "discrimination.json").is_file():
        return "2AFC table, threshold and PSE in discriminate/discrimination.json"
    if stage == "classify" and (out / "classify" / "classification.csv").is_file():
        return "held-out scans classified in classify/classification.csv"
    if stage == "table" and (out / "robot_table.json").is_file():
        return "per-plate table in robot_table.json"
    return "done"
