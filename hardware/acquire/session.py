"""One ``feeler acquire`` session: open everything in a safe order, then run the campaign.

Order: the plan and its layout, the C matrix, the camera, the stage (or the emulator;
a board in its alarm lock is homed or unlocked only when asked), the plan's moves against
the stage's soft limits and feed ceilings — every one of them can refuse with a one-line
error before the run directory is touched — then the run directory, locked for this
process (new, or reopened with ``resume``), and the campaign.
"""
from __future__ import annotations

import contextlib
from dataclasses import asdict
from pathlib import Path

import numpy as np

from feeler.errors import ArgumentError
from feeler.models.optics import OpticsParams
from feeler.rundir import write_json
from feeler.scene import load_scene, scene_as_dict

from .campaign import LATE_FRACTION, Setup, run_campaign
from .plan import check_moves, sample_times_s, scans_of
from .store import RunStore
from .world import VirtualWorld, layout_file, optics_of_plan, plan_layout

__all__ = ["load_plan", "c_from_calibration", "acquire"]


def load_plan(path: str | Path):
    """Load a ``scan-plan`` scene (``ArgumentError`` for another kind)."""
    plan = load_scene(path)
    if plan.scene.kind != "scan-plan":
        raise ArgumentError("--plan", str(path), f"a scan-plan scene, not {plan.scene.kind!r}")
    return plan


def c_from_calibration(directory: str | Path | None, *, accept_failed: bool = False) -> tuple[np.ndarray, str]:
    """C (3, 3) mm/N: the posterior mean of an M1 fit directory, or the optics' nominal C
    (a fit that failed its diagnostics only with ``accept_failed``).

    Raises:
        DataFileError: an unreadable fit directory. CalibrationFailed: a failed fit.
        ArgumentError: a fit without a C matrix (another model's posterior).
    """
    if directory is None:
        return OpticsParams().c_matrix, "nominal optics"
    from feeler.calib.fit import load, require_ok

    result = require_ok(load(directory), accept_failed=accept_failed, what=f"M1 fit {directory}")
    post = result.posterior["posterior"]
    if "C" not in post:
        raise ArgumentError("--calibration", str(directory), "an M1 fit directory (posterior with C)")
    c = np.asarray(post["C"].mean(("chain", "draw")).values, dtype=float)
    return c, f"posterior mean of {directory}"


#: how the note of :func:`_note_a_default_board` begins (tests of other lines leave it out)
DEFAULT_BOARD_NOTE = "feeler: note: the emulated stage (6000 mm/min per axis) runs this plan"


def _note_a_default_board(plan, plan_path, start_mm) -> None:
    """With --emulate, a line on stderr when a board at Grbl's default settings would refuse
    the plan: the emulated stage allows 6000 mm/min per axis (:data:`~.emulated.FAST_STAGE`),
    so a dry run of a plan with a 600 mm/min traverse ran to the end, though Grbl's default
    $110 = 500 mm/min refuses it on the real board (an outside audit)."""
    import sys

    from feeler.errors import SceneError
    from feeler.hardware.stage.limits import StageLimits

    try:
        check_moves(plan, plan_path, StageLimits(), "a board at Grbl's default settings", start_mm)
    except SceneError as exc:
        print(f"{DEFAULT_BOARD_NOTE}, but a board at Grbl's default settings would refuse it: {exc.key}: {exc.problem}",
              file=sys.stderr)


def acquire(plan_path: str | Path, out: str | Path, *, stage_port: str | None = None,
            camera_src: str | None = None, emulate: bool = False, resume: bool = False,
            force: bool = False, calibration: str | Path | None = None, accept_failed: bool = False,
            emulator_faults: tuple = (), unlock: bool = False, home: bool = False,
            late_fraction: float = LATE_FRACTION, observers: tuple = ()) -> dict:
    """Run (or resume) a campaign into ``out``; returns the summary.

    With ``emulate`` the stage is a Grbl emulator on a pty in a child process and, unless
    ``camera_src`` is given, the camera is the virtual camera of the plan's ``[virtual]``
    set-up, and ``emulator_faults`` (:class:`~feeler.hardware.emulators.Fault`) are injected
    into the emulator. Otherwise ``stage_port`` and ``camera_src`` are required. A board in
    its alarm lock (homing enabled, ``$22=1``) is homed with ``home`` or unlocked with
    ``unlock``; ``observers`` (:class:`~.progress.CampaignObserver`) watch the run.

    Raises (before the run directory is touched):
        ArgumentError: conflicting or missing arguments, a plan of another kind.
        SceneError: an invalid plan, or a move beyond the stage's soft limits or feed ceiling.
        DataFileError: a camera or video that cannot be opened, an unreadable fit directory.
        CalibrationFailed: ``calibration`` is a fit that failed its diagnostics (and not
            ``accept_failed``).
        PortError: a stage port that does not exist, is busy or is not permitted.
        StageLocked: a locked board and neither ``unlock`` nor ``home``.
        RunLocked: another process writes ``out``.
    Raises during the run (``samples.csv`` and ``journal.jsonl`` keep every sample so far,
    ``summary.json`` says why it stopped): DataFileError (a video that ends early, too many
    bad frames in a row), StageError (alarm, timeout, repeated bad lines).
    """
    from feeler.hardware.stage import ProtocolError, Stage, StageLocked

    from .cameras import CaptureCamera, VirtualCamera

    if resume and force:
        raise ArgumentError("--force", True, "not together with --resume (resume never overwrites)")
    if emulator_faults and not emulate:
        raise ArgumentError("--fault", len(emulator_faults), "only with --emulate")
    if not emulate and (stage_port is None or camera_src is None):
        raise ArgumentError("--stage/--camera", (stage_port, camera_src), "both, or --emulate")
    if unlock and home:
        raise ArgumentError("--unlock", True, "not together with --home (homing unlocks)")
    plan = load_plan(plan_path)
    c_mm_per_n, c_source = c_from_calibration(calibration, accept_failed=accept_failed)
    setup = Setup(plan, plan_layout(plan, plan_path), c_mm_per_n, optics_of_plan(plan), late_fraction)
    world = VirtualWorld.of_plan(plan, plan_path) if emulate and camera_src is None else None
    with contextlib.ExitStack() as stack:
        camera = None
        if camera_src is not None:
            camera = CaptureCamera(camera_src, (setup.layout.width_px, setup.layout.height_px))
            stack.callback(camera.close)
            if not resume:                   # a resumed run needs only the scans not yet done
                n_scans, n_samples = len(scans_of(plan)), len(sample_times_s(plan))
                camera.check_frames(n_scans * n_samples, f"the plan ({n_scans} scans of {n_samples} samples)")
        if emulate:
            from .emulated import campaign_emulator, emulated_stage

            stage_port = stack.enter_context(campaign_emulator(emulated_stage(plan), emulator_faults))
        try:
            stage = stack.enter_context(Stage.open(stage_port, unlock=unlock, home=home))
        except StageLocked as exc:
            raise StageLocked(exc.port, exc.alarm, "pass --home to home it ($H), or --unlock to clear the "
                              "lock without homing ($X)") from None
        except ProtocolError as exc:
            if home and exc.code == 5:
                raise ArgumentError("--home", True, f"a board with homing enabled ($22=1); {stage_port} "
                                    "has it disabled (pass --unlock, or nothing, instead)") from None
            raise
        # the emulator's /dev/pts path means nothing to the user who asked for --emulate
        check_moves(plan, plan_path, stage.limits, "the emulated stage" if emulate else stage.port, stage.target_mm)
        if emulate:
            _note_a_default_board(plan, plan_path, stage.target_mm)
        store = RunStore.resume(out, plan_path) if resume else RunStore.create(
            out, plan_path, force=force, layout_path=layout_file(plan, plan_path))
        stack.callback(store.close)
        store.observers.extend(observers)
        if world is not None:
            camera = VirtualCamera(world, store.out, plan.scene.seed)
            stack.callback(camera.close)
            if not resume:
                write_json(store.out / "truth.json", {"synthetic": True, "scene": scene_as_dict(plan),
                                                      "optics": asdict(world.optics),
                                                      "camera": asdict(world.camera)})
        extra = {"plan": str(plan_path), "stage": "emulator" if emulate else stage_port,
                 "camera": camera.name, "c_mm_per_n": setup.c_mm_per_n.tolist(), "c_source": c_source}
        return run_campaign(setup, stage, camera, store, extra)
