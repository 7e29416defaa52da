"""Calibrate a sensor element's force→displacement matrix C (M1).

DATASET is a directory with calibration.csv (ux_mm, uy_mm, uz_mm, fx_n, fy_n, fz_n, and
optionally point_id) and scene.toml whose [prior] table gives the nominal C₀ (as written
by `feeler simulate` for a sensor-calibration scene), or a calibration.csv with --c0.

Default model: the commanded U is exact and the measured F is noisy, so F = K U + η
with K = C⁻¹ is fitted and C = K⁻¹ reported (no attenuation). --eiv adds latent stage
errors on U (NUTS); --model forward is the naive U = C F + ε regression (biased; for
comparison only). Defaults: 4 chains x 1000 draws (exact, NUTS: 1000 warm-up); emcee
32 walkers run until their chains are 50 autocorrelation times long with R-hat <= 1.01
and bulk ESS >= 400 (first quarter discarded; the verdict fails at the cap of 200000
steps); --draws N --tune M runs emcee for exactly M + N steps.

The verdict also fails on what the data cannot support: design directions with no
information (all-zero displacements), a compliance ~10^3 off the nominal C0 (units: um
for mm, mN for N; both at once: forces scattering over 30x the noise prior's scale) or
off by a smaller usual slip (kgf or lbf for N, cm or inches for mm), a
prior that contradicts the data (prior-data conflict: widen --rel-sd or check C0), a
compliance C[i,i] whose sign the data do not pin (forces that do not follow the
displacements), and posterior predictive checks (lack of fit at replicated points,
outliers).
"""
from __future__ import annotations

from pathlib import Path

from feeler.commands._fit_output import add_fit_arguments, finish_fit

__all__ = ["HELP", "register", "run"]

HELP = "posterior of the force→displacement matrix C from a calibration campaign"


def register(parser) -> None:
    parser.add_argument("dataset", metavar="DATASET", help="directory with calibration.csv and scene.toml, or a CSV")
    parser.add_argument("--backend", choices=("exact", "nuts", "emcee"), default="exact",
                        help="exact conjugate (Gaussian noise; default), PyMC NUTS, or emcee")
    parser.add_argument("--noise", choices=("gaussian", "student"), default="gaussian",
                        help="force noise distribution (default gaussian; student: Student-t, --nu dof)")
    parser.add_argument("--nu", type=float, default=4.0, help="Student-t degrees of freedom (default 4)")
    parser.add_argument("--eiv", action="store_true",
                        help="errors-in-variables: latent stage error on U (needs --backend nuts)")
    parser.add_argument("--stage-sd-mm", type=float, default=None,
                        help="stage error sd for --eiv, mm (default: the scene's noise.stage_sd_mm or 0.001)")
    parser.add_argument("--model", choices=("inverse", "forward"), default="inverse",
                        help="inverse: F = K U + η (default); forward: naive U = C F + ε")
    parser.add_argument("--c0", type=float, nargs=9, default=None, metavar="C",
                        help="nominal C₀ row by row, mm/N (overrides the dataset's scene.toml)")
    parser.add_argument("--rel-sd", type=float, default=None, help="prior sd per entry / largest entry")
    parser.add_argument("--predict", type=float, nargs=3, action="append", default=[],
                        metavar=("FX", "FY", "FZ"), help="print the 90 %% predictive interval of U for this force, N")
    add_fit_arguments(parser, draws=None, tune=None)
    parser.set_defaults(run=run)


def run(args) -> int:
    import warnings

    import numpy as np

    from feeler.calib.fit import DiagnosticWarning
    from feeler.calib.matrix import fit_matrix, predict_u, read_calibration_csv
    from feeler.calib.progress import stage

    csv, scene = _locate(Path(args.dataset))
    data = read_calibration_csv(csv)
    prior, stage_sd, source = _prior(args, scene)
    rng = np.random.default_rng(args.seed)
    model = "eiv" if args.eiv else args.model
    emcee = args.backend == "emcee"               # emcee: run until converged unless --draws
    draws = args.draws if args.draws is not None else (None if emcee else 1000)
    tune = args.tune if args.tune is not None else (3000 if emcee else 1000)
    stage(f"fitting M1 ({args.backend} backend, {data.n} points)", args.progress)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DiagnosticWarning)     # the verdict is printed below
        result = fit_matrix(data, prior, model=model, noise=args.noise, backend=args.backend,
                            rng=rng, student_nu=args.nu, stage_sd_mm=stage_sd, chains=args.chains,
                            draws=draws, tune=tune, progress=args.progress)
    print(f"M1 force→displacement matrix: {data.n} points from {csv}, model {model}, "
          f"noise {args.noise}, backend {args.backend}; nominal C0 from {source}")
    for f in args.predict:
        p = predict_u(result, f, rng=rng, prob=0.9)
        cells = ", ".join(f"u{a} {m:.4f} [{lo:.4f}, {hi:.4f}]" for a, m, lo, hi in
                          zip("xyz", p["mean_mm"][0], p["lb_mm"][0], p["ub_mm"][0]))
        print(f"predicted U for F = {list(f)} N (90 %): {cells} mm")
    return finish_fit(result, args)


def _locate(path: Path):
    from feeler.errors import DataFileError

    if path.is_dir():
        csv, scene = path / "calibration.csv", path / "scene.toml"
        return csv, (scene if scene.is_file() else None)
    if path.suffix == ".csv":
        scene = path.with_name("scene.toml")
        return path, (scene if scene.is_file() else None)
    raise DataFileError(path, "not a dataset directory or a calibration CSV")


def _prior(args, scene_path):
    from feeler.calib.matrix import MatrixPrior
    from feeler.errors import ArgumentError

    c0, rel_sd, sigma_scale, stage_sd = None, 0.5, 0.1, 0.001
    if scene_path is not None:
        from feeler.scene import load_scene
        scene = load_scene(scene_path)
        if not hasattr(scene, "prior"):
            raise ArgumentError("DATASET", str(scene_path), "scene.toml must be a sensor-calibration scene")
        c0, rel_sd = scene.prior.c0_mm_per_n, scene.prior.rel_sd
        sigma_scale, stage_sd = scene.prior.sigma_f_scale_n, scene.noise.stage_sd_mm or 0.001
    if args.c0 is not None:
        c0 = tuple(tuple(args.c0[3 * i: 3 * i + 3]) for i in range(3))
    if c0 is None:
        raise ArgumentError("--c0", None, "the nominal matrix is needed: give --c0 (9 numbers, mm/N) "
                                          "or a dataset with scene.toml")
    if args.rel_sd is not None:
        rel_sd = args.rel_sd
    if args.stage_sd_mm is not None:
        stage_sd = args.stage_sd_mm
    source = "--c0" if args.c0 is not None else str(scene_path)
    return MatrixPrior(c0_mm_per_n=c0, rel_sd=rel_sd, sigma_f_scale_n=sigma_scale), stage_sd, source
