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
steps); --draws N --tune M runs emcee for exactly M + N steps. An option the chosen
backend would not use is refused before any work: --tune with exact, --chains with emcee
(its walkers are its chains), --tune with emcee without --draws (and --model forward
with --eiv, which fits the inverse model).

The verdict also fails on what the data cannot support: design directions with no
information (all-zero displacements), noise-free forces (residuals at rounding level:
NUTS and emcee are then not started), rows copied whatever their point ids, a
compliance ~10^3 off the nominal C0 (units: um for mm, mN for N; both at once: forces
scattering over 30x the noise prior's scale; along the pinned directions when the design
leaves some unidentified) or off by a smaller usual slip (kgf or lbf for N, cm or inches
for mm), a sensor much softer than C0 (told from swapped columns by C0's pattern), a
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
    parser.add_argument("--nu", type=float, default=None,
                        help="Student-t degrees of freedom (default 4; needs --noise student)")
    parser.add_argument("--eiv", action="store_true",
                        help="errors-in-variables: latent stage error on U (needs --backend nuts)")
    parser.add_argument("--stage-sd-mm", type=float, default=None,
                        help="stage error sd for --eiv, mm (default: the scene's noise.stage_sd_mm or 0.001; needs --eiv)")
    parser.add_argument("--model", choices=("inverse", "forward"), default="inverse",
                        help="inverse: F = K U + η (default); forward: naive U = C F + ε (not with --eiv)")
    parser.add_argument("--c0", type=float, nargs=9, default=None, metavar="C",
                        help="nominal C₀ row by row, mm/N (overrides the dataset's scene.toml)")
    parser.add_argument("--rel-sd", type=float, default=None, help="prior sd per entry / largest entry")
    parser.add_argument("--predict", type=float, nargs=3, action="append", default=[],
                        metavar=("FX", "FY", "FZ"), help="print the predictive median and 90 %% interval of U for this force, N "
                                                         "(|F| at most 10x the largest calibrated force)")
    from feeler.commands._checks import MAX_CHAINS, MAX_TOTAL_DRAWS, MAX_TUNE

    # --chains None unless typed: refused with emcee, whose walkers are its chains (_check_options)
    add_fit_arguments(parser, chains=None, draws=None, tune=None, helps={
        "chains": f"chains (default {DEFAULT_CHAINS}, at most {MAX_CHAINS}; exact and nuts only: emcee runs "
                  f"{EMCEE_WALKERS} walkers, stored as its chains)",
        "draws": f"kept draws per chain (default 1000; chains × draws at most {MAX_TOTAL_DRAWS}); emcee: run until "
                 f"converged unless --draws, then exactly --tune + --draws steps per walker (at most "
                 f"{MAX_TOTAL_DRAWS // EMCEE_WALKERS})",
        "tune": f"warm-up steps per chain (nuts: default 1000; emcee, with --draws only: default 3000; at most "
                f"{MAX_TUNE}; needs --backend nuts or emcee)"})
    parser.set_defaults(run=run)


def run(args) -> int:
    import warnings

    import numpy as np

    _check_options(args)

    from feeler.calib.fit import DiagnosticWarning
    from feeler.calib.matrix import NotSampled, fit_matrix, predict_u, read_calibration_csv
    from feeler.calib.progress import stage
    from feeler.commands._fit_output import verdict_text

    csv, scene = _locate(Path(args.dataset))
    data = read_calibration_csv(csv)
    prior, stage_sd, source = _prior(args, scene)
    f_max = float(np.max(np.linalg.norm(data.f_n, axis=1)))
    _check_predict_range(args.predict, f_max)
    rng = np.random.default_rng(args.seed)
    model = "eiv" if args.eiv else args.model
    emcee = args.backend == "emcee"               # emcee: run until converged unless --draws
    draws = args.draws if args.draws is not None else (None if emcee else 1000)
    tune = args.tune if args.tune is not None else (3000 if emcee else 1000)
    stage(f"fitting M1 ({args.backend} backend, {data.n} points)", args.progress)
    header = (f"M1 force→displacement matrix: {data.n} points from {csv}, model {model}, "
              f"noise {args.noise}, backend {args.backend}; nominal C0 from {source}")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DiagnosticWarning)     # the verdict is printed below
            result = fit_matrix(data, prior, model=model, noise=args.noise, backend=args.backend,
                                rng=rng, student_nu=args.nu, stage_sd_mm=stage_sd, chains=args.chains,
                                draws=draws, tune=tune, progress=args.progress)
    except NotSampled as exc:                  # noise-free data: nothing for NUTS or emcee to sample
        print(header)
        print(f"backend {args.backend} not run: these data leave it nothing to sample"
              + (f"; nothing written to {args.out}" if args.out else ""))
        print(verdict_text(exc.verdict))
        return 1
    print(header)
    for f in args.predict:
        p = predict_u(result, f, rng=rng, prob=0.9)
        cells = ", ".join(f"u{a} {m:.4f} [{lo:.4f}, {hi:.4f}]" for a, m, lo, hi in
                          zip("xyz", p["median_mm"][0], p["lb_mm"][0], p["ub_mm"][0]))
        print(f"predicted U for F = {list(f)} N (median [90 % interval]): {cells} mm")
        size = float(np.linalg.norm(f))
        if size > f_max:
            print(f"note: |F| = {size:.3g} N lies beyond the calibrated forces (the largest |F| {f_max:.3g} N): "
                  f"the prediction extrapolates the linear matrix to {size / f_max:.2g} times it")
    return finish_fit(result, args)


# --predict beyond this many times the largest calibrated |F| is refused: the matrix is linear
# only as far as the campaign pressed (an elastomer stiffens, and the data say nothing past their
# largest force), so a modest extrapolation is allowed with a note, while ×10 and more is no
# prediction but a slip: mN typed for N is ×1000, and 1e30 printed 30-digit displacements
PREDICT_RANGE = 10.0

#: --noise student's degrees of freedom unless --nu
DEFAULT_NU = 4.0

#: emcee's walkers (fit_matrix's default), stored as its chains
EMCEE_WALKERS = 32
#: --chains of the exact and NUTS backends unless typed
DEFAULT_CHAINS = 4


def _check_options(args) -> None:
    """The options' values and combinations, before the data are read (one line each)."""
    import math

    from feeler.errors import ArgumentError

    if args.nu is not None and args.noise != "student":       # an option the fit would not use: refused
        raise ArgumentError("--nu", args.nu, "needs --noise student (Gaussian noise has no degrees of freedom)")
    if args.stage_sd_mm is not None and not args.eiv:
        raise ArgumentError("--stage-sd-mm", args.stage_sd_mm, "needs --eiv (only the errors-in-variables model "
                                                               "has stage errors)")
    if args.tune is not None and args.backend == "exact":
        raise ArgumentError("--tune", args.tune, "needs --backend nuts or emcee (exact draws are independent: "
                                                 "no warm-up)")
    if args.tune is not None and args.backend == "emcee" and args.draws is None:
        raise ArgumentError("--tune", args.tune, "needs --draws with --backend emcee (without --draws the emcee "
                                                 "backend runs until its chains are 50 autocorrelation times long "
                                                 "and discards the first quarter of its steps)")
    if args.model == "forward" and args.eiv:
        raise ArgumentError("--model", args.model, "not used with --eiv (errors-in-variables fits the inverse "
                                                   "model F = K U + η with a latent stage error on U): leave out "
                                                   "one of them")
    from feeler.commands._checks import check_sizes, refuse_unused

    refuse_unused(args, {"chains": DEFAULT_CHAINS}, used=args.backend != "emcee",
                  needs=lambda name: f"needs --backend exact or nuts (the emcee backend runs {EMCEE_WALKERS} "
                                     f"walkers, stored as its chains, until converged or for --tune + --draws "
                                     f"steps)")
    if args.nu is None:
        args.nu = DEFAULT_NU
    if not (math.isfinite(args.nu) and args.nu > 0):
        raise ArgumentError("--nu", args.nu, "Student-t degrees of freedom: a finite number > 0")
    if args.stage_sd_mm is not None and not (math.isfinite(args.stage_sd_mm) and args.stage_sd_mm > 0):
        raise ArgumentError("--stage-sd-mm", args.stage_sd_mm, "the stage error sd: a finite number > 0 (mm)")
    if args.backend == "exact" and (args.noise != "gaussian" or args.eiv):
        raise ArgumentError("--backend", args.backend, "exact needs noise=gaussian and no --eiv; use --backend "
                                                       "nuts for --noise student or --eiv")
    if args.backend == "emcee" and args.eiv:
        raise ArgumentError("--backend", args.backend, "emcee cannot sample --eiv's latent stage errors; use "
                                                       "--backend nuts")
    from feeler.calib.psychometric.independent import check_draw_counts

    if args.backend != "emcee":          # the verdict's R-hat and ESS need these counts, before any work
        check_draw_counts(args.chains, 1000 if args.draws is None else args.draws, flag="--")
    elif args.draws is not None:         # emcee for exactly --tune + --draws steps: its 32 walkers are the chains
        check_draw_counts(EMCEE_WALKERS, args.draws, flag="--")
    if args.backend == "emcee" and args.draws is not None:     # 32 walkers are its chains, not --chains
        from feeler.commands._checks import MAX_TOTAL_DRAWS
        if args.draws * EMCEE_WALKERS > MAX_TOTAL_DRAWS:
            raise ArgumentError("--draws", args.draws, f"at most {MAX_TOTAL_DRAWS // EMCEE_WALKERS} with --backend "
                                f"emcee ({EMCEE_WALKERS} walkers × draws at most {MAX_TOTAL_DRAWS}: the posterior "
                                f"draws must fit in memory)")
    if args.backend != "emcee":
        check_sizes(args)                # chains × draws, now that --chains is filled in
    for f in args.predict:
        if not all(math.isfinite(v) for v in f):
            raise ArgumentError("--predict", list(f), "three finite forces FX FY FZ, N")


def _check_predict_range(forces, f_max: float) -> None:
    """Each --predict force within :data:`PREDICT_RANGE` times the largest calibrated |F|."""
    import numpy as np

    from feeler.errors import ArgumentError

    for f in forces:
        size = float(np.linalg.norm(f))
        if size > PREDICT_RANGE * f_max:
            raise ArgumentError("--predict", list(f), f"a force within {PREDICT_RANGE:g} times the calibrated "
                                                      f"ones (|F| <= {PREDICT_RANGE * f_max:.3g} N; the data's "
                                                      f"largest is {f_max:.3g} N): the matrix is untested beyond "
                                                      f"(forces in mN for N?)")


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
