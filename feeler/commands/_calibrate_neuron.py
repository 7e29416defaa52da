"""Calibrate the neuron's (a, τ, h) and the decoder noise σ from labelled plate scans (M2).

DATASET is a run directory of a robot-scan scene (scans.csv + scene.toml, as written by
`feeler simulate`), or a scans.csv with --length-mm. Each scan's label is its plate's
step (mm); the model is δ_k ~ Normal(max(a·P_k(τ) − h, 0), σ) with P_k(τ) the peak window
sum of strain = U_y / length. Backends: grid (exact posterior on an adaptive grid,
default, fastest), nuts (PyMC), emcee. The printed posterior predictive check says
whether the decoder fits the labels.
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
                        help="representative length for strain = U_y / length, mm (default: the scene's)")
    parser.add_argument("--emcee-steps", type=int, default=8000, help="emcee steps per walker (default 8000)")
    add_fit_arguments(parser, draws=1000)
    parser.set_defaults(run=run)


def run(args) -> int:
    import warnings

    from feeler.calib.neuron import DecoderMisfitWarning, data_from_scans, fit_neuron
    from feeler.datasets import read_scans

    csv, length_mm, kernel = locate_scans(Path(args.dataset), args.length_mm)
    scans = read_scans(csv)
    data = data_from_scans(scans, length_mm=length_mm, kernel=kernel)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DecoderMisfitWarning)          # printed below instead
        result = fit_neuron(data, backend=args.backend, seed=args.seed, chains=args.chains, draws=args.draws,
                            tune=args.tune, emcee_steps=args.emcee_steps, progress=args.progress)
    print(f"M2 neuron: {scans.step_mm.size} scans from {csv}, strain = U_y / {length_mm:g} mm, "
          f"backend {args.backend}")
    attrs = result.posterior["posterior"].attrs
    fits = attrs["ppc_coverage90"] >= 0.8 and attrs["ppc_p_value"] >= 0.01
    print(f"posterior predictive check: {100 * attrs['ppc_coverage90']:.0f} % of labels inside their 90 % "
          f"interval, per-plate bias p = {attrs['ppc_p_value']:.3f} -> "
          + ("the decoder fits" if fits else "the decoder is biased for some plates"))
    return finish_fit(result, args)


def locate_scans(path: Path, length_mm: float | None):
    """(scans.csv, length_mm, kernel) from a run directory or CSV (+ optional scene.toml)."""
    from feeler.errors import ArgumentError, DataFileError

    if path.is_dir():
        csv = path / "scans.csv"
    elif path.suffix == ".csv":
        csv = path
    else:
        raise DataFileError(path, "not a run directory or a scans CSV")
    scene_path = csv.with_name("scene.toml")
    kernel = "boxcar"
    if scene_path.is_file():
        from feeler.scene import load_scene
        scene = load_scene(scene_path)
        if not hasattr(scene, "neuron"):
            raise ArgumentError("DATASET", str(scene_path), "scene.toml must be a robot-scan scene")
        kernel = scene.neuron.kernel
        length_mm = scene.neuron.length_mm if length_mm is None else length_mm
    if length_mm is None or not length_mm > 0:
        raise ArgumentError("--length-mm", length_mm, "> 0 (or a dataset with scene.toml)")
    return csv, float(length_mm), kernel
