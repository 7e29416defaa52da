"""The calibration campaign stages of ``feeler demo`` (after the robot stages of
:mod:`feeler.demo`).

Each stage runs the same sub-command a user would type (through :func:`feeler.cli.main`,
in-process), so the demo and the CLI cannot drift apart. A stage's full output goes to
``OUT/logs/<stage>.txt``; the terminal gets the lines that matter (summary tables,
verdicts, the discrimination table) on stdout, and the command's progress on stderr (none
with --no-progress). A stage whose command exits non-zero is named and
the demo goes on with the stages that do not need its results (:data:`NEEDS`), so the
report still shows what the others found and the failed fit's verdict; the demo then
ends with :class:`DemoIncomplete`. Earlier results stay on disk.

Run-directory layout written here (the report reads it):

- ``sensor-calibration/`` simulated calibration campaign; ``m1/`` its M1 posterior;
- ``m2/`` the neuron's (a, τ, h, σ) posterior from ``four-plates/`` (with ``--scene``, the scene file's name);
- ``held-out/`` fresh four-plates scans (seed + 10⁸); ``classify/`` their classification;
- ``discriminate/`` the robot's 2AFC table, difference threshold, Weber fraction, PSE, and
  the curve behind the threshold (:mod:`feeler.demo.curve`);
- ``psychophysics/`` the synthetic human 2AFC data; ``m4/`` their psychometric fits;
- ``finger-route/`` τ and σ_d inferred from the human data through the finger chain;
- ``finger/`` strain histories of the finger-steps scene (skin level L1);
- ``benchmarks/`` the speed/accuracy tables of the last ``make bench``, when there are any;
  ``skin-ladder/`` and ``speed/`` what the demo measured itself (:mod:`feeler.demo.speed`);
- ``report.html`` and ``report.pdf`` (:mod:`feeler.reports`) from all of the above.
"""
from __future__ import annotations

import contextlib
import io
import re
import sys
from pathlib import Path

from feeler.errors import FeelerError

__all__ = ["CAMPAIGN_STAGES", "NEEDS", "StageFailed", "DemoIncomplete", "DemoInterrupted", "held_out_scene"]

DATA = Path(__file__).resolve().parents[2] / "datasets-synthetic"
HELD_OUT_SEED_OFFSET = 100_000_000


class StageFailed(FeelerError):
    """A demo stage whose command exited non-zero (its log names the reason)."""

    def __init__(self, stage: str, code: int, log: Path):
        self.stage, self.code, self.log = stage, code, log
        super().__init__(f"demo stage {stage!r} exited {code}; see {log}")


class DemoIncomplete(FeelerError):
    """The demo ran to its end with some stages failed (and the stages needing them
    skipped). Attributes: ``failed`` ({stage: StageFailed}), ``skipped`` (stage names),
    ``ctx`` (the demo's context, for its closing table)."""

    def __init__(self, failed: dict, skipped: list, ctx: dict):
        self.failed, self.skipped, self.ctx = failed, skipped, ctx
        first = next(iter(failed.values()))
        report = f"; the report shows what the others found: {ctx['report'].html}" if "report" in ctx else ""
        super().__init__(f"{len(failed)} demo stage{'s' if len(failed) > 1 else ''} failed: "
                         + ", ".join(f"{name!r} (exit {e.code}, see {e.log})" for name, e in failed.items())
                         + (f"; skipped as they need {'it' if len(failed) == 1 else 'them'}: "
                            f"{', '.join(repr(n) for n in skipped)}" if skipped else "") + report)
        self.code = first.code


class DemoInterrupted(KeyboardInterrupt):
    """Ctrl-C (SIGINT) stopped the demo during stage ``stage`` (None: between stages); the stages in ``done``
    had finished and their outputs stay in ``out``. No later stage ran, the report
    included, so no report mixes this run's results with an earlier run's. A
    KeyboardInterrupt, so that code catching that still sees an interrupt.

    Attributes: ``stage`` (the running stage's name), ``done`` (names, in order),
    ``out`` (the output directory), ``code`` (130, as for SIGINT)."""

    code = 130

    def __init__(self, stage: str | None, done: list, out: Path):
        self.stage, self.done, self.out = stage, list(done), Path(out)
        super().__init__(self.message())

    def message(self) -> str:
        """One line: what ran, what is kept, what is stale, how to run it again."""
        kept = (f"the finished stages' outputs are kept in {self.out} ({', '.join(self.done)})" if self.done
                else "no stage had finished")
        report = self.out / "report.html"
        stale = (f"; {report} and the outputs of the stages that did not run are an earlier run's"
                 if report.is_file() else "")
        when = f"during stage {self.stage!r}" if self.stage else "between stages"
        return (f"demo interrupted {when}: {kept}; no report was built{stale}; "
                f"run `feeler demo --out {self.out} --force` to run every stage again")


class _Capture(io.StringIO):
    """One of a command's two streams: kept apart (``getvalue``) and written, in order,
    into the stage's shared log; ``forward`` (if given) gets each whole line as it comes,
    called with sys.stdout and sys.stderr as they were outside the capture (a ``forward``
    that prints to sys.stderr would otherwise write into this stream again)."""

    def __init__(self, log: io.StringIO, forward=None):
        super().__init__()
        self._log, self._forward, self._partial = log, forward, ""
        self._outside = (sys.stdout, sys.stderr)

    def write(self, text: str) -> int:
        self._log.write(text)
        if self._forward is not None:
            *lines, self._partial = (self._partial + text).split("\n")
            for line in lines:
                self._say(line)
        return super().write(text)

    def _say(self, line: str) -> None:
        inside = (sys.stdout, sys.stderr)
        sys.stdout, sys.stderr = self._outside
        try:
            self._forward(line)
        finally:
            sys.stdout, sys.stderr = inside

    def flush_partial(self) -> None:
        if self._forward is not None and self._partial:
            self._say(self._partial)
        self._partial = ""


def _run(ctx: dict, stage: str, argv: list[str], keep) -> None:
    """Run ``feeler argv`` in-process, log everything, echo the lines ``keep`` selects.

    ``keep`` selects from the command's stdout (its results), echoed with ``ctx["print"]``.
    Its stderr (the first line, progress, warnings) goes to the log, and to ``ctx["say"]``
    (the demo's stage lines: stderr) line by line as it comes, unless the demo runs with
    ``progress`` False: then the command runs with --no-progress too and only a failed
    command's stderr (its error) is echoed. Progress lines within the results (the
    discrimination's "2AFC pairs: 3/6 done") reached stdout, even with --no-progress.

    Raises:
        StageFailed: the command exited non-zero.
        KeyboardInterrupt: it was interrupted (exit 130: the in-process command caught the
            Ctrl-C itself, so it is raised again here to stop the demo; the log is written).
    """
    from feeler.cli import main

    logs = ctx["out"] / "logs"
    logs.mkdir(exist_ok=True)
    say = ctx.get("say", ctx["print"])
    quiet = ctx.get("progress") is False
    if quiet and "--no-progress" not in argv:
        argv = [*argv, "--no-progress"]
    log = io.StringIO()
    out, err = _Capture(log), _Capture(log, forward=None if quiet else say)
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = main(argv)
    finally:
        err.flush_partial()
        (logs / f"{stage}.txt").write_text(f"$ feeler {' '.join(argv)}\n{log.getvalue()}", encoding="utf-8")
    if code == 130:                       # Ctrl-C: `main` caught it and said "interrupted" in the log
        raise KeyboardInterrupt(stage)
    if code != 0:
        if out.getvalue().strip():
            ctx["print"](out.getvalue().rstrip())
        if quiet and err.getvalue().strip():           # otherwise it was said as it came
            say(err.getvalue().rstrip())
        raise StageFailed(stage, code, logs / f"{stage}.txt")
    shown = keep(out.getvalue().splitlines())
    if shown:
        ctx["print"]("\n".join(shown))


def _from(marker: str):
    """Keep the lines from the first one containing ``marker`` to the end."""
    def keep(lines):
        idx = next((i for i, line in enumerate(lines) if marker in line), len(lines))
        return lines[idx:]
    return keep


def _matching(pattern: str):
    return lambda lines: [line for line in lines if re.search(pattern, line)]


def held_out_scene(scene_path: Path, dest: Path) -> Path:
    """A copy of a robot-scan scene with its seed moved by 10⁸: fresh scans, same design. The
    move wraps round 2**63 (TOML's integer range, which a seed must keep): a scene seed within
    10⁸ of 2**63 - 1 failed the held-out stage (a fixer helper noticed)."""
    from feeler.scene import SEED_MAX

    text = scene_path.read_text(encoding="utf-8")
    new, n = re.subn(r"(?m)^(seed\s*=\s*)(\d+)",
                     lambda m: f"{m[1]}{(int(m[2]) + HELD_OUT_SEED_OFFSET) % (SEED_MAX + 1)}", text, count=1)
    if n != 1:
        raise FeelerError(f"{scene_path}: no 'seed = N' line to derive held-out scans from")
    dest.write_text(new, encoding="utf-8")
    return dest


def _force(ctx) -> list[str]:
    return ["--force"] if ctx["force"] else []


def _scene(ctx: dict, name: str) -> Path:
    """The scene file of ``name`` ("sensor-calibration", ...): the shipped one unless the
    caller of :func:`feeler.demo.run_demo` gave another (small sizes for tests)."""
    return Path(ctx.get("scenes", {}).get(name, DATA / f"{name}.toml"))


def _calibrate_sensor(ctx: dict) -> None:
    out = ctx["out"]
    _run(ctx, "simulate-sensor-calibration",
         ["simulate", str(_scene(ctx, "sensor-calibration")), "--out", str(out / "sensor-calibration"),
          *_force(ctx)], keep=lambda lines: [])
    ctx["print"]("\nM1 — the sensor's force→displacement matrix C (exact conjugate posterior):")
    _run(ctx, "calibrate-sensor", ["calibrate", "sensor", str(out / "sensor-calibration"), "--out",
                                   str(out / "m1"), *_force(ctx)],
         keep=lambda lines: [line for line in _from("name")(lines) if not line.lstrip().startswith("K[")])


def _calibrate_neuron(ctx: dict) -> None:
    scene = ctx.get("scene")
    n = len(scene.surface.heights_mm) if scene is not None else 4
    plates = {2: "two", 3: "three", 4: "four", 5: "five", 6: "six"}.get(n, str(n))
    ctx["print"](f"\nM2 — the neuron's (a, τ, h) and decoder noise σ from the {plates} plates (exact grid):")
    _run(ctx, "calibrate-neuron", ["calibrate", "neuron", str(ctx["run_dir"]), "--out", str(ctx["out"] / "m2"),
                                   "--no-progress", *_force(ctx)], keep=_from("name"))


def _classify(ctx: dict) -> None:
    out = ctx["out"]
    scene = held_out_scene(ctx["scene_path"], out / "held-out-scene.toml")
    _run(ctx, "simulate-held-out", ["simulate", str(scene), "--out", str(out / "held-out"), *_force(ctx)],
         keep=lambda lines: [])
    ctx["print"]("\nClassification of fresh (held-out) scans with confidence:")
    _run(ctx, "classify", ["classify", str(out / "m2"), str(out / "held-out"), "--out", str(out / "classify"),
                           *_force(ctx)], keep=_matching(r"classified as|wrote"))


def _discriminate(ctx: dict) -> None:
    ctx["print"]("\nM3 — the robot's discrimination (2AFC proportion correct):")
    from feeler.demo.curve import write_threshold_curve

    scans = ctx.get("discriminate_scans")
    _run(ctx, "discriminate", ["discriminate", str(ctx["out"] / "m2"), "--out", str(ctx["out"] / "discriminate"),
                               *(["--n-scans", str(scans)] if scans else []), *_force(ctx)], keep=_from("low mm"))
    curve = write_threshold_curve(ctx["out"] / "m2", ctx["out"] / "discriminate", **({"n_scans": scans} if scans else {}))
    if curve is not None:
        ctx["print"](f"the curve behind the threshold: {curve}")


def _psychophysics(ctx: dict) -> None:
    out = ctx["out"]
    _run(ctx, "simulate-psychophysics", ["simulate", str(_scene(ctx, "psychophysics-2afc")), "--out",
                                         str(out / "psychophysics"), *_force(ctx)], keep=lambda lines: [])
    ctx["print"]("\nM4 — human psychometric functions (SYNTHETIC 2AFC data), pooled rows:")
    _run(ctx, "fit-psychophysics", ["fit", "psychophysics", str(out / "psychophysics" / "trials.csv"),
                                    "--backend", "exact", "--out", str(out / "m4"), *_force(ctx)],
         keep=lambda lines: [line for line in lines if line.strip().startswith(("subject", "all", "wrote"))])


def _finger_route(ctx: dict) -> None:
    ctx["print"]("\nThe model route: τ and decision noise σ_d from the (SYNTHETIC) human data "
                 "through skin L0 → neuron → observer:")
    _run(ctx, "fit-finger-route", ["fit", "finger-route", str(ctx["out"] / "psychophysics" / "trials.csv"),
                                   "--out", str(ctx["out"] / "finger-route"), "--no-progress", *_force(ctx)],
         keep=_matching(r"^\s*(tau_s|sigma_d)|τ|tau ≤|P\(|verdict"))


def _finger(ctx: dict) -> None:
    ctx["print"]("\nFinger skin: strain histories at the corpuscle for the paper's steps (finger-steps):")
    _run(ctx, "simulate-finger-steps", ["simulate", str(_scene(ctx, "finger-steps")), "--out",
                                        str(ctx["out"] / "finger"), *_force(ctx)], keep=_matching(r"wrote"))


def _speed_tables(ctx: dict) -> None:
    """Copy the speed/accuracy tables of the last ``make bench`` (runs/benchmarks/*.csv),
    then measure small versions of what they do not cover (:mod:`feeler.demo.speed`)."""
    import shutil

    from feeler.demo.speed import measure_trades

    src = Path(ctx["out"]).resolve().parent / "benchmarks"
    tables = sorted(src.glob("*.csv")) if src.is_dir() else []
    if tables:
        dest = ctx["out"] / "benchmarks"
        dest.mkdir(exist_ok=True)
        for table in tables:
            shutil.copyfile(table, dest / table.name)
        (dest / "SOURCE.txt").write_text(f"copied from {src} (written by `make bench`)\n", encoding="utf-8")
        ctx["print"](f"\nspeed/accuracy tables from {src}: {', '.join(t.name for t in tables)}")
    else:
        ctx["print"](f"\nspeed/accuracy: no `make bench` tables in {src}; measuring small versions now")
    if not ctx.get("measure_trades", True):
        return
    measure_trades(ctx["out"], DATA, echo=ctx["print"])


def _report(ctx: dict) -> None:
    from feeler.calib.progress import stages
    from feeler.reports import build_report

    step, close = stages("report", ctx.get("progress"))      # its sections, figures and PDF pages
    try:
        report = build_report(ctx["out"], progress=step)
    finally:
        close()
    ctx["report"] = report
    ctx["print"](f"\nreport: {report.html}" + (f" and {report.pdf} ({report.n_pages} pages)" if report.pdf else ""))


#: stages that read another's results: skipped when that one failed (classify and
#: discriminate refuse a failed neuron fit). The finger route reads the trials that the
#: psychophysics stage simulates before its M4 fit, so a failed M4 verdict leaves it its data
NEEDS = {"classify": "calibrate neuron", "discriminate": "calibrate neuron"}

#: (name, func(ctx)) appended to :data:`feeler.demo.STAGES`
CAMPAIGN_STAGES = [("calibrate sensor", _calibrate_sensor), ("calibrate neuron", _calibrate_neuron),
                   ("classify", _classify), ("discriminate", _discriminate),
                   ("psychophysics", _psychophysics), ("finger route", _finger_route), ("finger skin", _finger),
                   ("speed/accuracy", _speed_tables),
                   ("report", _report)]
