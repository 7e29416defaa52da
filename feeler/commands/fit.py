"""Fit human 2AFC psychophysics data (M4). Sub-commands:

  psychophysics  psychometric functions (cumulative normal with lapse, optional
                 beta-binomial overdispersion, subjects pooled hierarchically):
                 difference thresholds and PSEs with 95 % intervals per speed
  finger-route   τ and the decision noise σ_d through the finger chain (skin → FA-I
                 neuron → observer), reported beside the paper's "τ ≤ 300 ms"

DATA.csv has the columns subject, standard_um, standard_speed_mm_s, comparison_um,
comparison_speed_mm_s, n_trials, n_comparison_higher ('#' lines are comments). The
difference threshold is the distance from the PSE to the 75 % point of
P(comparison judged higher). Exit status 1 when the posterior fails its diagnostics.
"""
from __future__ import annotations

import argparse

from feeler.commands._fit_output import add_fit_arguments, print_summary

__all__ = ["NAME", "HELP", "register", "run_psychophysics", "run_finger_route"]

NAME = "fit"
HELP = "fit 2AFC psychophysics: psychometric functions (M4) or τ through the finger chain"


def register(parser) -> None:
    sub = parser.add_subparsers(title="what to fit", metavar="WHAT")
    psy = sub.add_parser("psychophysics", help="difference thresholds and PSEs per subject and speed",
                         description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    psy.add_argument("data", metavar="DATA.csv", help="2AFC trial table")
    psy.add_argument("--backend", choices=("nuts", "laplace"), default="nuts",
                     help="PyMC NUTS (default) or per-subject MAP + Laplace (fast, deterministic)")
    psy.add_argument("--separate", action="store_true",
                     help="NUTS without pooling: independent priors per subject ('all' = every trial as one observer)")
    psy.add_argument("--overdispersion", action="store_true", help="beta-binomial counts")
    psy.add_argument("--target-accept", type=float, default=0.99,
                     help="NUTS target acceptance rate (default 0.99)")
    add_fit_arguments(psy)
    psy.set_defaults(run=run_psychophysics)

    route = sub.add_parser("finger-route", help="posterior of τ and σ_d through skin → neuron → observer",
                           description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    route.add_argument("data", metavar="DATA.csv", help="2AFC trial table")
    route.add_argument("--level", choices=("l0", "l1", "l2"), default="l0", help="skin fidelity (default l0)")
    route.add_argument("--check-level", choices=("l0", "l1", "l2"), default=None,
                       help="recompute the choice probabilities at the posterior mean with this level")
    route.add_argument("--n-tau", type=int, default=121, help="τ grid nodes, 1 ms–10 s (default 121)")
    add_fit_arguments(route)
    route.set_defaults(run=run_finger_route)

    def no_target(args) -> int:
        parser.print_help()
        return 2
    parser.set_defaults(run=no_target)


def _banner(note: str) -> None:
    if note:
        print("DATA: " + note.replace("\n", "\nDATA: "))


def run_psychophysics(args) -> int:
    import numpy as np

    from feeler.calib.psychometric.fit import fit_psychometric, save_psychometric, threshold_table
    from feeler.psydata import read_trials, synthetic_note

    trials = read_trials(args.data)
    note = synthetic_note(trials)
    _banner(note)
    result = fit_psychometric(trials, rng=np.random.default_rng(args.seed), backend=args.backend,
                              hierarchical=not args.separate, overdispersion=args.overdispersion,
                              chains=args.chains, draws=args.draws, tune=args.tune,
                              target_accept=args.target_accept, progressbar=bool(args.progress))
    print_summary(result)
    table = threshold_table(result, observed=trials)
    print("thresholds (µm; posterior mean and 95 % interval; DT = PSE → 75 % point):")
    print(table.to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    if args.out:
        out = save_psychometric(result, trials, args.out, force=args.force, note=note)
        print(f"wrote {out / 'thresholds.csv'}, posterior.nc, summary.csv, verdict.json")
    return 0 if result.verdict.ok else 1


def run_finger_route(args) -> int:
    import numpy as np

    from feeler.calib.psychometric.finger_route import RouteGrid, fit_finger_route, predict_p_higher, tau_report
    from feeler.errors import ArgumentError
    from feeler.psydata import read_trials, synthetic_note
    from feeler.rundir import prepare_out_dir, write_json

    if args.n_tau < 2:
        raise ArgumentError("--n-tau", args.n_tau, "needs at least 2 grid nodes")
    trials = read_trials(args.data)
    note = synthetic_note(trials)
    _banner(note)
    if args.out:
        prepare_out_dir(args.out, ("posterior.nc", "summary.csv", "verdict.json", "tau_report.json"),
                        force=args.force)
    result = fit_finger_route(trials, rng=np.random.default_rng(args.seed), grid=RouteGrid(n_tau=args.n_tau),
                              level=args.level, chains=args.chains, draws=args.draws)
    print_summary(result)
    report = tau_report(result) | {"synthetic_data": bool(note), "data_note": note}
    if args.check_level:
        mean = result.summary.set_index("name")["mean"]
        kw = dict(tau_s=float(mean["tau_s"]), sigma_d_um=float(mean["sigma_d_um"]),
                  lapse=float(mean["lapse"]))
        p_fit = predict_p_higher(trials, level=args.level, **kw)
        p_chk = predict_p_higher(trials, level=args.check_level, **kw)
        report["check"] = {"level": args.check_level, "max_abs_dp": float(np.max(np.abs(p_fit - p_chk)))}
    lo, hi = report["tau_eti95_s"]
    print(f"tau: posterior mean {1e3 * report['tau_mean_s']:.1f} ms, 95 % interval "
          f"[{1e3 * lo:.1f}, {1e3 * hi:.1f}] ms; P(tau <= 300 ms | data) = {report['p_tau_le_300ms']:.3f}")
    print(f"paper: {report['paper']}")
    if "check" in report:
        print(f"check at the posterior mean with {args.check_level}: max |ΔP| = "
              f"{report['check']['max_abs_dp']:.4f}")
    if args.out:
        out = result.save(args.out, force=True)
        write_json(out / "tau_report.json", report)
        print(f"wrote {out / 'tau_report.json'}, posterior.nc, summary.csv, verdict.json")
    return 0 if result.verdict.ok else 1
