"""``feeler demo`` (what ``make demo`` runs): the robot stages, then the campaign.

The demo is a list of stages (:data:`STAGES`), each ``func(ctx) -> None`` reading and
adding entries of one shared context dict. The robot stages below come first; the
calibration campaign and the report follow (:mod:`feeler.demo.campaign`).

1. ``simulate``: the robot-scan scene (``four-plates``, or ``--scene``) into ``OUT/<its file
   name without .toml>/`` (``OUT/four-plates/``; via :mod:`feeler.simulate`);
2. ``features``: read ``scans.csv`` back, run the neuron (z(t) and peak z per scan), the
   ΔU_y jump and the raw U̇_y peak;
3. ``table``: per plate, peak z and raw U̇_y mean ± sd and the ΔU_y jump; 2AFC proportion
   correct of each adjacent plate pair by peak z and by raw U̇_y; printed and saved as
   ``OUT/robot_table.json``;
4. ``figures``: ``OUT/fig7_delta_uy.png`` (ΔU_y vs x), ``OUT/fig8_uy_rate.png``
   (U̇_y vs t), ``OUT/fig9_pulse_density.png`` (normalised z vs t), one scan per plate.
"""
from __future__ import annotations

import time
from pathlib import Path
from typing import Callable

import numpy as np

import feeler
from feeler.calib.progress import duration
from feeler.datasets import proportion_correct, read_scans, strain
from feeler.demo.campaign import NEEDS, DemoIncomplete, DemoInterrupted, StageFailed
from feeler.rundir import prepare_out_dir, write_json
from feeler.scene import load_scene

__all__ = ["DEFAULT_SCENE", "STAGES", "FIGURES", "run_demo"]

DEFAULT_SCENE = Path(feeler.__file__).resolve().parents[1] / "datasets-synthetic" / "four-plates.toml"
FIGURES = ("fig7_delta_uy.png", "fig8_uy_rate.png", "fig9_pulse_density.png")


def _simulate(ctx: dict) -> None:
    from feeler.simulate import run_simulation

    ctx["run_dir"] = run_simulation(ctx["scene_path"], ctx["out"] / robot_dir(ctx["scene_path"]), force=ctx["force"],
                                    progress=ctx.get("progress"))
    ctx["scene"] = load_scene(ctx["run_dir"] / "scene.toml")


def _features(ctx: dict) -> None:
    from feeler.models import neuron
    from feeler.simulate import features_of

    scene, scans = ctx["scene"], read_scans(ctx["run_dir"])
    nrn = scene.neuron
    ctx["scans"], ctx["features"] = scans, features_of(scene, scans)
    ctx["z"] = neuron.per_time_base(
        lambda s, t: neuron.pulse_density(s, t, a=nrn.a, tau=nrn.tau_s, h=nrn.h, kernel=nrn.kernel),
        strain(scans.uy_mm, nrn.length_mm), scans.t_s)


def _table(ctx: dict) -> None:
    scans, f = ctx["scans"], ctx["features"]
    steps = list(dict.fromkeys(scans.step_mm.tolist()))
    rows, pairs = [], []
    for step in steps:
        sel = scans.step_mm == step
        rows.append({"step_mm": step, "n_scans": int(sel.sum()),
                     "peak_z_mean": float(f.peak_z[sel].mean()), "peak_z_sd": float(f.peak_z[sel].std(ddof=1)),
                     "raw_rate_mean_mm_s": float(f.peak_rate_uy_mm_s[sel].mean()),
                     "raw_rate_sd_mm_s": float(f.peak_rate_uy_mm_s[sel].std(ddof=1)),
                     "jump_uy_mean_mm": float(f.jump_uy_mm[sel].mean())})
    for lo, hi in zip(steps[:-1], steps[1:]):
        a, b = scans.step_mm == lo, scans.step_mm == hi
        pairs.append({"lower_mm": lo, "higher_mm": hi,
                      "pc_peak_z": proportion_correct(f.peak_z[a], f.peak_z[b]),
                      "pc_raw_rate": proportion_correct(f.peak_rate_uy_mm_s[a], f.peak_rate_uy_mm_s[b])})
    ctx["table"] = {"plates": rows, "adjacent_pairs": pairs}
    write_json(ctx["out"] / "robot_table.json", ctx["table"])
    lines = ["step_mm  n   peak z (V) mean ± sd      raw |dU_y/dt| (mm/s) mean ± sd   dU_y jump (mm)"]
    for r in rows:
        lines.append(f"{r['step_mm']:6.3f} {r['n_scans']:3d}   {r['peak_z_mean']:.5f} ± {r['peak_z_sd']:.5f}"
                     f"      {r['raw_rate_mean_mm_s']:.4f} ± {r['raw_rate_sd_mm_s']:.4f}"
                     f"              {r['jump_uy_mean_mm']:+.4f}")
    lines.append("2AFC proportion correct, adjacent plates:   by peak z   by raw dU_y/dt peak")
    for p in pairs:
        lines.append(f"  {p['lower_mm']:.3f} vs {p['higher_mm']:.3f} mm{'':22s}{p['pc_peak_z']:.3f}       {p['pc_raw_rate']:.3f}")
    ctx["print"]("\n".join(lines))


def _figures(ctx: dict) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scans, z, out = ctx["scans"], ctx["z"], ctx["out"]
    steps = list(dict.fromkeys(scans.step_mm.tolist()))
    first = [int(np.flatnonzero(scans.step_mm == s)[0]) for s in steps]
    t = scans.t_s                      # each scan's own sample times (n_scans, n_time)
    z_norm = z / max(z[first[-1]].max(), np.finfo(float).tiny)
    panels = [("fig7_delta_uy.png", "x (mm)", "ΔU_y = U_y − U_y0 (mm)", "Fig. 7: vertical displacement",
               lambda i: (scans.x_mm[i], scans.uy_mm[i] - scans.uy_mm[i, 0])),
              ("fig8_uy_rate.png", "t (s)", "U̇_y (mm/s)", "Fig. 8: rate of vertical displacement",
               lambda i: (t[i, 1:], np.diff(scans.uy_mm[i]) / np.diff(t[i]))),
              ("fig9_pulse_density.png", "t (s)", "normalised pulse density Z", "Fig. 9: pulse density",
               lambda i: (t[i], z_norm[i]))]
    for name, xlabel, ylabel, title, series in panels:
        fig, ax = plt.subplots(figsize=(6, 4))
        for step, i in zip(steps, first):
            ax.plot(*series(i), label=f"δ = {step:g} mm")
        ax.set(xlabel=xlabel, ylabel=ylabel, title=title)
        ax.legend()
        fig.tight_layout()
        fig.savefig(out / name, dpi=100)
        plt.close(fig)


def _campaign_stages():
    from feeler.demo.campaign import CAMPAIGN_STAGES
    return CAMPAIGN_STAGES


#: the demo's stages, in order: (name, func(ctx)); the campaign stages follow the robot's
STAGES: list[tuple[str, Callable[[dict], None]]] = [
    ("simulate", _simulate), ("features", _features), ("table", _table), ("figures", _figures),
    *_campaign_stages()]


def robot_dir(scene_path: Path) -> str:
    """The run directory of the demo's robot scans under OUT: the scene file's name without
    ``.toml`` (``four-plates``), so that ``--scene`` scans are not filed as four-plates."""
    return Path(scene_path).stem


def _results(scene_path: Path) -> tuple[str, ...]:
    """Files whose presence means an earlier demo's results (overwritten only with force)."""
    return ("robot_table.json", *FIGURES, f"{robot_dir(scene_path)}/scans.csv")


def _check_robot_scene(scene_path: Path) -> None:
    """The demo's robot scene read before any stage: a robot-scan scene with at least two
    plates (the neuron calibration pins nothing from one). A finger-steps or sensor-calibration
    scene ran a stage and then failed on a missing scans.csv; one plate ran all the stages.

    Raises:
        SceneError: the file does not validate, is another kind, or has one plate.
    """
    from feeler.errors import SceneError
    from feeler.scene import load_scene

    scene = load_scene(scene_path)
    kind = scene.scene.kind
    if kind != "robot-scan":
        raise SceneError(scene_path, "scene.kind", f"{kind!r}: demo --scene takes a robot-scan scene (as "
                                                   "datasets-synthetic/four-plates.toml); the demo simulates the "
                                                   "sensor-calibration, finger-steps and psychophysics scenes itself")
    heights = scene.surface.heights_mm
    if len(heights) < 2:
        raise SceneError(scene_path, "surface.heights_mm", f"{list(heights)}: one plate; the demo calibrates the "
                                                           "neuron on at least 2 plates (4 as in the paper)")


def run_demo(out: str | Path, *, force: bool = False, scene_path: str | Path | None = None,
             stages=None, echo: Callable[[str], None] = print, scenes: dict | None = None,
             discriminate_scans: int | None = None, progress: bool | None = None,
             stage_echo: Callable[[str], None] | None = None) -> dict:
    """Run the demo stages into ``out``; returns the context (scene, scans, features, table...).

    Args:
        echo: prints the stages' results (tables, verdicts): the commands' stdout lines
            that matter.
        stage_echo: prints the line before each stage, a stage's failure and the stderr
            of the commands the stages run (their progress, warnings and errors; only errors
            when ``progress`` is False) (default ``echo``; the command gives stderr, where
            progress goes).
        scene_path: the robot-scan scene (default the shipped four-plates).
        scenes: other scene files by name ("sensor-calibration", "psychophysics-2afc",
            "finger-steps") instead of the shipped ones (smaller runs, e.g. in tests).
        discriminate_scans: touches per height for the discrimination (default the command's).
        progress: False drops the ``[i/n] stage ... (time so far)`` line before each stage
            and the stages' own progress (simulation, report, and that of the commands they
            run, which get --no-progress); None: as `feeler --progress` off a terminal or on one.

    Raises:
        DemoIncomplete: after the last stage, when some failed (the stages needing them
            skipped, :data:`~feeler.demo.campaign.NEEDS`); its ``ctx`` is the context.
        DemoInterrupted: Ctrl-C during a stage; no later stage runs (the report would mix
            this run's results with an earlier run's), the finished ones' outputs stay.
        OverwriteError: ``out`` holds demo results and ``force`` is false.
        RunLocked: another demo is writing ``out`` (its PID in the message).
    """
    from feeler.hardware.acquire.lock import lock_run_dir, release_run_dir

    # two demos into one directory (two `make demo` on a shared machine) would overwrite each
    # other's files stage by stage: the second is refused, naming the first one's PID
    scene_path = Path(scene_path or DEFAULT_SCENE)
    _check_robot_scene(scene_path)
    if not force:                # refused before anything in ``out`` changes (the lock file included)
        prepare_out_dir(out, _results(scene_path), force=False)
    lock = lock_run_dir(out, then="")
    try:
        out = prepare_out_dir(out, _results(scene_path), force=force)
        say = stage_echo or echo
        ctx = {"out": out, "force": force, "scene_path": scene_path, "print": echo, "say": say,
               "seconds": {}, "cpu_seconds": {}, "scenes": dict(scenes or {}),
               "discriminate_scans": discriminate_scans, "progress": progress}
        todo = STAGES if stages is None else stages
        start = time.perf_counter()
        failed, skipped, running = {}, [], None
        try:
            for i, (name, stage) in enumerate(todo, 1):
                if NEEDS.get(name) in failed:
                    skipped.append(name)
                    say(f"[{i}/{len(todo)}] {name}: skipped, it needs {NEEDS[name]}, which failed")
                    continue
                if progress is not False:
                    so_far = f" ({duration(time.perf_counter() - start)} so far)" if i > 1 else ""
                    say(f"[{i}/{len(todo)}] {name} ...{so_far}")
                t0, c0, running = time.perf_counter(), time.process_time(), name
                try:
                    stage(ctx)
                except StageFailed as exc:             # the others still run: the report shows them all
                    failed[name] = exc
                    say(f"{name}: FAILED ({exc}); going on with the stages that do not need it")
                ctx["seconds"][name] = time.perf_counter() - t0
                ctx["cpu_seconds"][name] = time.process_time() - c0
                running = None
        except KeyboardInterrupt:                      # stop at once: the stages after it would mix runs
            raise DemoInterrupted(running, [n for n in ctx["seconds"] if n not in failed], out) from None
        if failed:
            raise DemoIncomplete(failed, skipped, ctx)
        return ctx
    finally:
        release_run_dir(lock)
