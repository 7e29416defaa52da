"""Calibrate the neuron's (a, τ, h) and the decoder noise σ from labelled plate scans (M2).

DATASET is a run directory of a robot-scan scene (scans.csv + scene.toml, as written by
`feeler simulate` or `feeler acquire`), or a scans.csv with --length-mm. Each scan's
label is its plate's step (mm). P_k(τ) is the peak window sum of strain = U_y / length;
per plate, P ~ Normal(μ_c, σ_c) with the noise σ_c constant, growing with the step, or
free per plate; or per plate and mode (two-mode, two-mode-growing): a touch snaps onto
the upper level or rides over the edge, read from its scan, and each has its own mean,
each mode its own spread and windows (--noise; auto picks by leave-one-out prediction of
the labels, a two-mode model when the touches show both modes unless a one-mode one
predicts clearly better, per-plate only when it wins by more than two standard errors;
the "decoder noise" line says so when the best score is not the choice). The
window τ is weighted by how well the decoder predicts each left-out label; the decoded
height is z = a·P − h on the least-squares line through the plates. Backends: grid
(exact, default, fastest: --chains × --draws), nuts (PyMC: --chains, --draws, --tune),
emcee (32 walkers run until their chains are 50 autocorrelation times long, at most
200000 steps, or exactly --emcee-steps); an option the chosen backend would not use is refused before any work
(--chains, --draws or --tune with emcee, say). The fit records the scene of
DATASET, which `feeler discriminate` then simulates. The verdict fails when the data
cannot pin the decoder down (one plate, noise-free scans, a window any value of which
fits), when units look wrong (µm for mm, steps in cm or inches, ms for s), or when the leave-one-out check
finds a plate whose 90 % intervals cover too few or too many of its scans to be
compatible with covering 85–95 % (a binomial test of its scans, Bonferroni-corrected over
the plates: a plate of 6 scans all inside passes). The fit also
says how its training scans read when each is left out (how many read as their own plate,
and the log score per scan, beside the plates' shares alone), for the set and per mode,
and names a mode that reads no better than those shares.
"""
from __future__ import annotations

from pathlib import Path

from feeler.commands._fit_output import add_fit_arguments, finish_fit

__all__ = ["HELP", "register", "run"]

HELP = "posterior of the neuron's (a, tau, h) and sigma from labelled plate scans"


def register(parser) -> None:
    parser.add_argument("dataset", metavar="DATASET", help="run directory with scans.csv and scene.toml, or a CSV")
    parser.add_argument("--backend", choices=("grid", "nuts", "emcee"), default="grid",
                        help="grid (exact, default), PyMC NUTS, or emcee")
    parser.add_argument("--length-mm", type=float, default=None,
                        help="representative length for strain = U_y / length, mm, at most 1000 (default: the "
                             "scene's)")
    parser.add_argument("--noise", choices=("auto", "constant", "growing", "per-plate", "two-mode", "two-mode-growing"),
                        default="auto",
                        help="decoder noise model (default auto: chosen by leave-one-out prediction; a one-mode "
                             "model over a two-mode one, or per-plate, only when it wins by more than two "
                             "standard errors). two-mode: "
                             "touches that snap onto the upper level and touches that ride over the edge (read "
                             "from each scan) get their own mean and each mode its own sd (one for both when a "
                             "mode has few scans), and each mode is read at its own windows; two-mode-growing: "
                             "those sds grow with the step. Grid backend only")
    parser.add_argument("--emcee-steps", type=int, default=None,
                        help="emcee: run exactly this many steps per walker, the first quarter discarded as "
                             "warm-up (the verdict fails when they are under 50 autocorrelation times); default: run "
                             "until 50 autocorrelation times, at most 200000 steps; 100-200000; needs --backend emcee")
    from feeler.commands._checks import MAX_CHAINS, MAX_TOTAL_DRAWS, MAX_TUNE

    # None unless typed: each is refused with a backend that would not use it (_check_backend_options)
    add_fit_arguments(parser, chains=None, draws=None, tune=None, helps={
        "chains": f"chains (default {SAMPLER_DEFAULTS['chains']}, at most {MAX_CHAINS}; grid and nuts only: "
                  f"emcee runs {EMCEE_WALKERS} walkers)",
        "draws": f"kept draws per chain (default {SAMPLER_DEFAULTS['draws']}; chains × draws at most "
                 f"{MAX_TOTAL_DRAWS}; grid and nuts only: emcee runs until its chains are 50 autocorrelation "
                 f"times long, or --emcee-steps)",
        "tune": f"NUTS warm-up steps per chain (default {NUTS_ONLY['tune']}, at most {MAX_TUNE}; needs --backend "
                f"nuts)"})
    parser.set_defaults(run=run)


#: emcee's walkers, stored as its chains (its steps: --emcee-steps, or until converged)
EMCEE_WALKERS = 32
#: --chains and --draws, and their defaults: the grid's exact draws and NUTS's chains
SAMPLER_DEFAULTS = {"chains": 4, "draws": 1000}
#: NUTS's warm-up, and its default
NUTS_ONLY = {"tune": 1000}
#: what each backend draws with, for the refusal of an option it would not use
BACKEND_USES = {"grid": "--chains × --draws exact draws",
                "nuts": "--chains chains of --tune warm-up and --draws kept steps",
                "emcee": f"{EMCEE_WALKERS} walkers until their chains are 50 autocorrelation times long, or for "
                         f"--emcee-steps steps"}


def _check_backend_options(args) -> None:
    """Refuse, before any work, an option the chosen backend would not use (--chains and
    --draws with emcee ran and said nothing: an outside audit), naming the backend and what
    it draws with; then fill in the defaults and check the sizes and counts."""
    from feeler.commands._checks import check_sizes, refuse_unused

    backend = args.backend
    uses = BACKEND_USES[backend]
    refuse_unused(args, SAMPLER_DEFAULTS, used=backend != "emcee",
                  needs=lambda name: f"needs --backend grid or nuts (the emcee backend runs {uses})")
    refuse_unused(args, {"emcee_steps": None}, used=backend == "emcee",
                  needs=lambda name: f"needs --backend emcee (the {backend} backend runs {uses})")
    refuse_unused(args, NUTS_ONLY, used=backend == "nuts",
                  needs=lambda name: f"needs --backend nuts (the {backend} backend has no warm-up: it runs {uses})")
    check_sizes(args)                   # chains × draws, now that both are known
    if backend != "emcee":
        from feeler.calib.psychometric.independent import check_draw_counts
        check_draw_counts(args.chains, args.draws, flag="--")     # the verdict's R-hat and ESS, before any work


def _scores(scores: dict, n_scans: int) -> str:
    """The noise models' leave-one-out log scores per scan as printed; those that are -inf
    (a scan the model gives probability 0 given the others: shuffled labels) are named
    together, not printed as '-inf'."""
    import math

    shown = [f"{k} {v / n_scans:+.3f}" for k, v in scores.items() if math.isfinite(v)]
    lost = [k for k, v in scores.items() if not math.isfinite(v)]
    if lost:
        shown.append(f"{', '.join(lost)} none: some scan has probability 0 given the others")
    return ", ".join(shown)


def _passed_over(passed: dict | None, n_scans: int) -> str:
    """Why the model of the best score is not the one chosen (calib.neuron.window.choose_noise):
    its lead is within two standard errors of the difference; "" when it is the choice."""
    if not passed:
        return ""
    lead, two_se = passed["lead"] / n_scans, passed["two_se"] / n_scans
    rule = ("per-plate is chosen only when it wins by more" if passed["rule"] == "per-plate" else
            "a one-mode model replaces a two-mode one only when it wins by more")
    return (f"; {passed['top']} not chosen: its lead over {passed['chosen']}, {lead:+.3f} per scan, is within two "
            f"standard errors of the difference ({two_se:.3f} per scan); {rule}")


def run(args) -> int:
    import warnings

    from feeler.calib.neuron import DecoderMisfitWarning, data_from_scans, fit_neuron
    from feeler.calib.neuron.fit import reading_text
    from feeler.datasets import read_scans

    import json

    from feeler.calib.fit import DiagnosticWarning
    from feeler.calib.progress import stage
    from feeler.errors import ArgumentError, DataFileError

    _check_backend_options(args)
    if args.emcee_steps is not None and args.emcee_steps < 100:
        raise ArgumentError("--emcee-steps", args.emcee_steps, ">= 100")
    if args.backend != "grid" and args.noise.startswith("two-mode"):       # before the scans are read
        raise ArgumentError("--noise", args.noise, f"constant, growing or per-plate with --backend {args.backend} "
                            "(the two-mode models are drawn exactly, by the grid backend)")
    csv, length_mm, kernel = locate_scans(Path(args.dataset), args.length_mm)
    scene_path = _scene_beside(csv)
    scene_toml = scene_path.read_text(encoding="utf-8") if scene_path.is_file() else None
    stage(f"reading {csv}", args.progress)
    scans = read_scans(csv)
    data = data_from_scans(scans, length_mm=length_mm, kernel=kernel)
    stage(f"fitting M2 ({args.backend} backend, {scans.step_mm.size} scans)", args.progress)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DecoderMisfitWarning)          # printed below instead
        warnings.simplefilter("ignore", DiagnosticWarning)
        try:
            result = fit_neuron(data, backend=args.backend, noise=args.noise, seed=args.seed, chains=args.chains,
                                draws=args.draws, tune=args.tune, emcee_steps=args.emcee_steps, walkers=EMCEE_WALKERS,
                                progress=args.progress, scene_toml=scene_toml,
                                scene_path=str(scene_path.resolve()) if scene_toml else None)
        except ArgumentError as err:
            column = {"step_mm": "step_mm", "scans": "uy_mm", "t_s": "t_s"}.get(err.name)   # the data's fault: name the file
            if column is None:
                raise
            raise DataFileError(csv, f"column {column}: {err.value}: {err.allowed}") from None
    print(f"M2 neuron: {scans.step_mm.size} scans from {csv}, strain = U_y / {length_mm:g} mm, "
          f"backend {args.backend}" + ("" if scene_toml else "; no scene.toml: discriminate will need --scene"))
    attrs = result.posterior["posterior"].attrs
    scores = json.loads(attrs.get("noise_scores", "{}"))
    checks = json.loads(attrs.get("checks", "{}"))
    steps = result.posterior["observed_data"]["plate_steps_mm"].values
    modes = json.loads(attrs.get("touch_modes", "{}"))
    why = ""
    if str(attrs["noise"]).startswith("two-mode") and modes:
        why = (f"; {modes['snaps']} of {modes['snaps'] + modes['rides']} touches of plates with a riser snapped onto "
               f"the upper level, the others rode over the edge, and each is read by its mode (chosen unless a "
               f"one-mode model scores better by two standard errors: left out, a touch takes its cell's mean with it)")
    passed = json.loads(attrs.get("noise_passed_over", "null"))
    print(f"decoder noise: {attrs['noise']}" + (f" (leave-one-out log score per scan: {_scores(scores, scans.step_mm.size)}"
                                                 f"{_passed_over(passed, scans.step_mm.size)})" if scores else "") + why)
    reading = json.loads(attrs.get("loo_reading", "null"))
    if reading:
        print(f"leave-one-out reading: {reading_text(reading)}")
    for line in mode_lines(json.loads(attrs.get("mode_decoders", "{}"))):
        print(line)
    if "loo_coverage90" in checks:
        print("posterior predictive check (leave-one-out): labels inside their 90 % interval per plate: " + ", ".join(
            f"{s + 0.0:g} mm " + (f"{100 * c:.0f} %" if c == c else "- (one scan)")
            for s, c in zip(steps, checks["loo_coverage90"])))
    print("note: a, tau_s and h are the decoder's (z = a·P_tau − h fitted to the labels, tau_s the window "
          "that predicts them best), not the neuron parameters of a scene; a is in mm per unit strain (P, the peak "
          "window sum of |strain changes|, is a strain), as the report labels it")
    for line in checks.get("window_edge", []):
        print(f"note: {line}")
    if steps.size == 2:
        print(f"note: two plates: the line z = a·P − h passes through both plates' means exactly, so no plate checks "
              f"it; steps other than {steps[0] + 0.0:g} and {steps[1] + 0.0:g} mm (classify of other scans, "
              f"discriminate's pairs and threshold) are read along a line these data cannot test (a third plate "
              f"would)")
    left_out = _undecodable_note(result)
    if left_out:
        print(left_out + " (the summary leaves them out too)")
    return finish_fit(result, args)


def mode_lines(by_mode: dict) -> list[str]:
    """What the fit says of its decoder per mode (the ``mode_decoders`` attribute): each
    mode's window, γ and leave-one-out accuracy, and a note for a mode that reads no
    better than its plates' shares."""
    if not by_mode:
        return []
    lines = ["decoded by mode: " + ", ".join(
        f"{k}s at a window of about {v['tau_s']:.3g} s (gamma {v['sharpness']:.3g}, {v['scans']} scans"
        + (f"; {100 * v['loo']['accuracy']:.0f} % read as their plate when left out, the most common "
           f"plate alone {100 * v['loo']['base_accuracy']:.0f} %" if "loo" in v else "") + ")"
        for k, v in by_mode.items()) + "; each mode weighted by how its own touches are told apart (the "
        "summary's tau_s weighs both together)"]
    for k, v in by_mode.items():
        if "loo" in v and not v["loo"]["informative"]:
            lines.append(f"note: {k}s read no better when left out than their plates' shares alone (log score per "
                         f"scan {v['loo']['log_score']:+.3f} against {v['loo']['base_log_score']:+.3f}): a new "
                         f"{k}'s plate probabilities say little")
    return lines


def _undecodable_note(result) -> str | None:
    """The decoder's note on draws it leaves out, or None (none, or too many: the verdict says so)."""
    from feeler.calib.neuron.decoder import DecoderDraws
    from feeler.errors import ArgumentError

    try:
        return DecoderDraws.from_result(result, by_mode=False).note
    except ArgumentError:
        return None


def _scene_beside(source: Path) -> Path:
    """The scene.toml of a scans CSV (beside it) or of a directory of scan files (in it)."""
    return source / "scene.toml" if source.is_dir() else source.with_name("scene.toml")


def locate_scans(path: Path, length_mm: float | None):
    """(scans.csv, or the directory of one file per scan; length_mm, kernel) from a run
    directory, a CSV or a directory of scan files (+ optional scene.toml)."""
    from feeler.errors import ArgumentError, DataFileError
    from feeler.rundir import what_it_is

    if path.is_dir():
        from feeler.calib.neuron.live.scan_csv import no_scans_problem
        from feeler.datasets import scan_files

        csv = path / "scans.csv"
        if scan_files(path):                 # one file per scan: read_scans joins them
            csv = path
        elif not csv.is_file():
            raise DataFileError(path, no_scans_problem(path))
    elif path.suffix == ".csv":
        csv = path
        kind = what_it_is(csv, expected="scans.csv")         # a trial table or a calibration file, say
        if kind:
            raise DataFileError(csv, f"not robot scans: {kind}")
    else:
        raise DataFileError(path, "not a run directory or a scans CSV")
    scene_path = _scene_beside(csv)
    kernel = "boxcar"
    if scene_path.is_file():
        from feeler.scene import load_scene
        scene = load_scene(scene_path)
        if not hasattr(scene, "neuron"):
            if path.is_dir():
                hint = what_it_is(path, expected="scans.csv")
                raise ArgumentError("DATASET", str(scene_path), "scene.toml must be a robot-scan scene"
                                    + (f"; {hint}" if hint else ""))
            kind = getattr(getattr(scene, "scene", None), "kind", "another kind of")
            raise ArgumentError("DATASET", str(csv), f"the scene.toml beside it is a {kind!r} scene, not the "
                                "robot-scan scene of these scans; move the CSV to a directory of its own (and give "
                                "--length-mm) or take that scene.toml away")
        kernel = scene.neuron.kernel
        length_mm = scene.neuron.length_mm if length_mm is None else length_mm
    if length_mm is None:
        where = (f"the scan files of {csv.name}/ have no scene.toml with them" if csv.is_dir()
                 else f"{csv.name} has no scene.toml beside it")
        raise ArgumentError("--length-mm", None, f"needed: {where} to give the element's representative length; "
                            "give --length-mm (mm; strain = U_y / length)")
    from feeler.scene import param_bounds
    from feeler.scenes.robot_scan import Neuron

    top = param_bounds(Neuron, "length_mm")[1]     # the scene schema's own range
    if not 0 < length_mm <= top:
        # the element pitch is 3 mm; 3000 (um typed for mm) passed with verdict ok (an outside audit)
        slip = f"; {length_mm:g} looks like µm: {length_mm / 1000:g} mm?" if top < length_mm <= 1000 * top else ""
        raise ArgumentError("--length-mm", length_mm, f"a length in (0, {top:g}] mm (strain = U_y / length){slip}")
    return csv, float(length_mm), kernel
