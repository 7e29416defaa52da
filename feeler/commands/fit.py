"""Fit forced-choice psychophysics data (M4). Sub-commands:

  psychophysics  psychometric functions (cumulative normal with lapse, optional
                 beta-binomial overdispersion; subjects alone, or pooled hierarchically
                 with NUTS): PSE, difference threshold, the threshold and slope at any
                 proportion (--pc), goodness of fit, per subject and condition
  finger-route   τ and the decision noise σ_d through the finger chain (skin → FA-I
                 neuron → observer), reported beside the paper's "τ ≤ 300 ms"

DATA.csv: subject, standard_um, standard_speed_mm_s, comparison_um, comparison_speed_mm_s
and either counts (n_trials with n_comparison_higher, or n_correct for nAFC) or one row
per trial (comparison_higher, or correct for nAFC, as 1/0), aggregated on reading; '#'
lines are comments.

Comparison design: P(comparison judged higher) = λ/2 + (1 − λ)·Φ((x − PSE)/σ); the
difference threshold DT is the distance from the PSE to the 75 % point. nAFC (--nafc N,
n_correct data): P(correct) = 1/N + (1 − 1/N)(1 − λ)·Φ((x − m)/σ). A lapse is a guess.
Priors are scaled to each condition's range of tested levels unless set with --prior-*;
the output states them in words.

Backends: exact (default; the posterior integrated on an adaptive grid, deterministic),
laplace (a Gaussian approximation: approximate, warns when its bounds disagree with the
exact posterior), nuts (PyMC; hierarchical unless --separate). Exit status 1 when the
verdict fails: sampler diagnostics, a model that does not fit its data (posterior
predictive p of the deviance), prior–data conflict, heights that look like mm or nm, or
data that cannot pin the function down.
"""
from __future__ import annotations

from feeler.commands._fit_output import add_fit_arguments, print_summary

__all__ = ["NAME", "HELP", "register", "run_psychophysics", "run_finger_route"]

NAME = "fit"
HELP = "fit forced-choice psychophysics: psychometric functions (M4) or τ through the finger chain"


def _own_doc(what: str, example: str, backends: str | None = None) -> str:
    """A sub-command's --help text: ``what`` it does, the shared data text of this module's
    docstring (from "DATA.csv"), its ``backends`` paragraph (default the docstring's, for
    the psychometric fits), and an example."""
    data = __doc__[__doc__.index("DATA.csv"):__doc__.index("Backends:")]
    backends = backends or __doc__[__doc__.index("Backends:"):]
    return f"{what}\n\n{data}{backends}\nExample:\n    {example}\n"


def _add_psychophysics(sub) -> None:
    psy = sub.add_parser("psychophysics", help="PSE, thresholds and slopes per subject and condition",
                         description=_own_doc(
                             "Psychometric functions (M4: cumulative normal with lapse, optional beta-binomial\n"
                             "overdispersion; subjects alone, or pooled hierarchically with NUTS): PSE, difference\n"
                             "threshold, the threshold and slope at any proportion (--pc), goodness of fit, per\n"
                             "subject and condition.\n\n"
                             "A psignifit data matrix (height in µm, n correct or higher, n trials per row; header\n"
                             "optional; commas, semicolons, tabs or spaces) is read with the design it lacks:\n"
                             "--standard-um, --speed-mm-s (and --subject, --comparison-speed-mm-s); a directory of\n"
                             "them reads as one subject per file, named after it. psignifit's \"equal asymptote\" is\n"
                             "the comparison design, its \"2AFC\" --nafc 2.",
                             "feeler simulate datasets-synthetic/psychophysics-2afc.toml --out runs/humans\n"
                             "    feeler fit psychophysics runs/humans/trials.csv --out runs/m4"))
    psy.add_argument("data", metavar="DATA.csv", help="trial table (counts or one row per trial), a run "
                                                     "directory holding trials.csv, a psignifit data matrix, or "
                                                     "a directory of them (one per subject)")
    psy.add_argument("--backend", choices=("exact", "laplace", "nuts"), default="exact",
                     help="exact: the posterior integrated on an adaptive grid (default); laplace: a "
                          "Gaussian approximation (approximate; warns where its bounds disagree with the "
                          "exact grid); nuts: PyMC, hierarchical unless --separate")
    psy.add_argument("--separate", action="store_true",
                     help="nuts without pooling: independent priors per subject (needs --backend nuts)")
    psy.add_argument("--all", dest="all_estimand", choices=("pooled", "population"), default=None,
                     help="what the 'all' rows estimate: the pooled trials fitted as one observer, or the "
                          "population mean of the hierarchical model (default: population for hierarchical "
                          "nuts, else pooled)")
    psy.add_argument("--nafc", type=int, default=None, metavar="N",
                     help="nAFC proportion-correct data (n_correct / correct columns) with N alternatives")
    psy.add_argument("--pc", type=float, default=None,
                     help="proportion for the threshold and slope columns (default 0.75; nAFC: (1 + 1/N)/2)")
    psy.add_argument("--lapse", choices=("subject", "condition"), default="subject",
                     help="one lapse rate per subject (default) or per subject and condition (as psignifit)")
    psy.add_argument("--overdispersion", action="store_true", help="beta-binomial counts")
    psy.add_argument("--prior-pse-sd", type=float, default=None, metavar="UM",
                     help="sd of the PSE prior in µm (default: half the range of tested levels)")
    psy.add_argument("--prior-sigma", type=float, default=None, metavar="UM",
                     help="median of the σ prior in µm (default: a quarter of the range of tested levels)")
    psy.add_argument("--prior-sigma-log-sd", type=float, default=1.0, metavar="S",
                     help="sd of log σ in the σ prior (default 1)")
    psy.add_argument("--prior-lapse", default="2,18", metavar="A,B",
                     help="lapse = 0.5·Beta(A, B) (default 2,18: mean 0.05)")
    psy.add_argument("--target-accept", type=float, default=None,
                     help="NUTS target acceptance rate (default 0.99; needs --backend nuts)")
    psy.add_argument("--no-plots", action="store_true", help="with --out, skip the curves/*.png")
    matrix = psy.add_argument_group("a psignifit data matrix (height µm, n correct or higher, n trials per row)",
                                    "the design such a file does not hold, the same for every row")
    matrix.add_argument("--standard-um", type=float, default=None, metavar="UM",
                        help="the standard's height, µm (0 in nAFC detection)")
    matrix.add_argument("--speed-mm-s", type=float, default=None, metavar="V",
                        help="scan speed of the standard (and of the comparison), mm/s")
    matrix.add_argument("--comparison-speed-mm-s", type=float, default=None, metavar="V",
                        help="scan speed of the comparison, mm/s (default --speed-mm-s)")
    matrix.add_argument("--subject", default=None, metavar="NAME", help="the subject (default: the file name)")
    from feeler.commands._checks import MAX_TUNE

    add_fit_arguments(psy, tune=None, helps={"tune": f"NUTS warm-up steps per chain (default {NUTS_ONLY['tune']}, at "
                                                     f"most {MAX_TUNE}; needs --backend nuts)"})
    psy.set_defaults(run=run_psychophysics)


def register(parser) -> None:
    sub = parser.add_subparsers(title="what to fit", metavar="WHAT")
    _add_psychophysics(sub)
    route = sub.add_parser("finger-route", help="posterior of τ and σ_d through skin → neuron → observer",
                           description=ROUTE_HELP)
    route.add_argument("data", metavar="DATA.csv", help="2AFC trial table (comparison design), or a run "
                                                       "directory holding trials.csv")
    route.add_argument("--level", choices=("l0", "l1", "l2"), default="l0", help="skin fidelity (default l0)")
    route.add_argument("--check-level", choices=("l0", "l1", "l2"), default=None,
                       help="recompute the choice probabilities at the posterior mean with this level")
    route.add_argument("--n-tau", type=int, default=121, help="τ grid nodes, 1 ms–10 s (default 121, 2-1000)")
    _add_route_output(route)
    route.set_defaults(run=run_finger_route)


ROUTE_HELP = """\
The neuron's window τ and the decision noise σ_d from 2AFC trials, through the finger
chain (skin → FA-I neuron → observer), reported beside the paper's "τ ≤ 300 ms".

DATA.csv: subject, standard_um, standard_speed_mm_s, comparison_um, comparison_speed_mm_s
and either counts (n_trials with n_comparison_higher) or one row per trial
(comparison_higher as 1/0), aggregated on reading; '#' lines are comments; a run
directory is read as its trials.csv. Comparison design only: no nAFC (n_correct) data,
no psignifit data matrix. Rows with n_trials = 0 are left out, with a note.

Model: each step's accepted height ŝ comes from the skin (--level), the neuron's peak
window sum over τ and a conversion κ(τ) calibrated at each speed on the paper's 5–15 µm
steps; P(comparison judged higher) = λ/2 + (1 − λ)·Φ((ŝ_cmp − ŝ_std)/σ_d). One τ, σ_d and
lapse λ for all subjects pooled. Priors (fixed, stated in the output): τ log-uniform on
1 ms–10 s (--n-tau nodes), σ_d log-uniform on 0.05–20 µm, λ = 0.5·Beta(2, 18).

The posterior of (τ, σ_d, λ) is computed exactly on a grid; the summary table is made
of --chains × --draws independent draws from it (no sampler, no warm-up: R-hat and ESS
are shown, and the verdict checks only their number: at least 2 chains of 4 draws and
400 draws in all, refused before any work otherwise). τ shows only in how judgements
change with the scan speed: the data need trials at more than one speed pair.

Exit status 1 when the verdict fails: τ not pinned by the data, a posterior piling
against a grid bound, heights that look like mm or nm, speeds off a fingertip's, or
subjects whose decision noise disagrees with the pooled fit (at chance, or always
right: more than 4 times the pooled σ_d apart). Bad input: one line, exit status 2.

Example:
    feeler fit finger-route runs/humans/trials.csv --out runs/route
"""


def _add_route_output(parser) -> None:
    """--out, --force, --seed, --chains, --draws, --progress: no --tune (no sampler)."""
    from feeler.commands._fit_output import FIT_FILES

    parser.add_argument("--out", default=None, metavar="DIR",
                        help="write posterior.nc, summary.csv, verdict.json and tau_report.json into DIR")
    parser.add_argument("--force", action="store_true", help="overwrite an earlier fit in DIR")
    parser.add_argument("--seed", type=int, default=0, help="seed of the draws from the grid (default 0)")
    parser.add_argument("--chains", type=int, default=4,
                        help="groups of independent draws from the grid posterior (default 4; 2-64)")
    parser.add_argument("--draws", type=int, default=1000,
                        help="independent draws per group (default 1000; chains × draws 400-200000)")
    parser.add_argument("--progress", action="store_true", default=None, help="always show progress")
    parser.add_argument("--no-progress", dest="progress", action="store_false", help="never show progress")
    parser.set_defaults(out_files=FIT_FILES + ("tau_report.json",))


def _without_empty_rows(trials):
    """(``trials`` without its rows of n_trials = 0, a note naming them or "").

    Such a row holds no trial: it would add a tested level without responses to the
    identifiability checks, or a subject with no data."""
    empty = (trials["n_trials"] == 0).to_numpy()
    if not empty.any():
        return trials, ""
    kept = trials[~empty].reset_index(drop=True)
    kept.attrs = dict(trials.attrs)
    rows = trials[empty]
    named = "; ".join(f"{r.subject} {r.standard_um:g} µm at {r.standard_speed_mm_s:g} mm/s vs {r.comparison_um:g} µm "
                      f"at {r.comparison_speed_mm_s:g} mm/s" for r in rows.head(3).itertuples())
    more = f"; and {len(rows) - 3} more" if len(rows) > 3 else ""
    gone = [str(x) for x in dict.fromkeys(trials["subject"]) if x not in set(kept["subject"])]
    return kept, (f"{len(rows)} row{'s' if len(rows) != 1 else ''} with n_trials = 0 left out (no trials to fit): "
                  f"{named}{more}" + (f"; subject(s) {', '.join(gone)} had no other rows" if gone else ""))


def _banner(note: str) -> None:
    if note:
        print("DATA: " + note.replace("\n", "\nDATA: "))


def _priors(args):
    """The Priors of the --prior-* options (each checked, naming its option)."""
    import math

    from feeler.calib.psychometric.model.priors import Priors
    from feeler.errors import ArgumentError

    for flag, value in (("--prior-pse-sd", args.prior_pse_sd), ("--prior-sigma", args.prior_sigma),
                        ("--prior-sigma-log-sd", args.prior_sigma_log_sd)):
        if value is not None and not (math.isfinite(value) and value > 0):
            raise ArgumentError(flag, value, "must be a finite number > 0 (µm for heights)")
    try:
        a, b = (float(v) for v in args.prior_lapse.split(","))
    except ValueError:
        raise ArgumentError("--prior-lapse", args.prior_lapse, "two numbers A,B (lapse = 0.5·Beta(A, B))") from None
    if not (math.isfinite(a) and math.isfinite(b) and a >= 1 and b > 0):
        raise ArgumentError("--prior-lapse", args.prior_lapse, "needs A >= 1 and B > 0")
    return Priors(pse_sd_um=args.prior_pse_sd, sigma_um=args.prior_sigma,
                  log_sigma_sd=args.prior_sigma_log_sd, lapse_a=a, lapse_b=b)


def _report_warnings(caught) -> None:
    """One formatted line per warning the fit raised (the verdict lists its problems)."""
    from feeler.calib.fit import DiagnosticWarning

    seen = set()
    for w in caught:
        if issubclass(w.category, DiagnosticWarning):
            continue
        text = str(w.message).strip().splitlines()[0] if str(w.message).strip() else w.category.__name__
        if text not in seen:
            seen.add(text)
            print(f"warning: {text}")


_SHOW = ("subject", "standard_um", "standard_speed_mm_s", "comparison_speed_mm_s", "pse_um", "pse_lb_um",
         "pse_ub_um", "dt_um", "dt_lb_um", "dt_ub_um", "threshold_um", "threshold_lb_um", "threshold_ub_um",
         "slope_per_um", "lapse", "deviance", "gof_p")


#: NUTS's options and their defaults: the exact grid and Laplace have no sampler to set
NUTS_ONLY = {"separate": False, "target_accept": 0.99, "tune": 1000}


def _check_nuts_only(args) -> None:
    """Refuse a NUTS option with another backend (it would be ignored), then fill in the defaults."""
    from feeler.commands._checks import refuse_unused

    refuse_unused(args, NUTS_ONLY, used=args.backend == "nuts",
                  needs=lambda name: f"needs --backend nuts (the {args.backend} backend has no sampler"
                                     + (" and no hierarchy to leave out)" if name == "separate" else ")"))


def run_psychophysics(args) -> int:
    from feeler.calib.progress import stage
    from feeler.calib.psychometric.fit import check_arguments
    from feeler.calib.psychometric.model.task import Task

    from feeler.calib.psychometric.independent import check_draw_counts

    _check_nuts_only(args)
    task = Task(args.nafc)                     # every option checked before any work
    if args.pc is not None:
        task.check_pc(args.pc, "--pc")
    check_draw_counts(args.chains, args.draws, flag="--")
    check_arguments(args.backend, args.chains, args.draws, args.tune, args.target_accept, args.lapse,
                    args.all_estimand, not args.separate, args.pc, args.nafc)
    stage(f"fit psychophysics: reading {args.data}", args.progress)     # stderr: stdout is the result
    import warnings

    import numpy as np
    import pandas as pd

    from feeler.calib.psychometric.fit import fit_psychometric, save_psychometric, threshold_table
    from feeler.calib.psychometric.outputs.display import display_table
    from feeler.psydata import MatrixDesign, read_trials, synthetic_note
    from feeler.rundir import prepare_out_dir

    priors = _priors(args)
    design = None
    if any(v is not None for v in (args.standard_um, args.speed_mm_s, args.comparison_speed_mm_s, args.subject)):
        design = MatrixDesign(subject=args.subject, standard_um=args.standard_um, speed_mm_s=args.speed_mm_s,
                              comparison_speed_mm_s=args.comparison_speed_mm_s, nafc=args.nafc is not None).check()
    if args.out:
        prepare_out_dir(args.out, ("thresholds.csv", "posterior.nc", "summary.csv", "verdict.json")
                        + (() if args.no_plots else ("curves/index.csv",)), force=args.force)
    trials, dropped = _without_empty_rows(read_trials(args.data, design=design))
    note = synthetic_note(trials)
    _banner(note)
    if dropped:
        print(f"note: {dropped}")
    rows = trials.attrs.get("trial_rows", 0)
    what = (f"{trials['subject'].nunique()} subject(s), {int(trials['n_trials'].sum())} trials"
            f"{f' (aggregated from {rows} trial rows)' if rows else ''}, backend {args.backend}")
    stage(f"fitting {what}", args.progress)                 # stderr; the result's header below on stdout
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = fit_psychometric(trials, rng=np.random.default_rng(args.seed), backend=args.backend,
                                  hierarchical=not args.separate, overdispersion=args.overdispersion,
                                  priors=priors, lapse_per=args.lapse, all_estimand=args.all_estimand,
                                  nafc=args.nafc, pc=args.pc, chains=args.chains, draws=args.draws,
                                  tune=args.tune, target_accept=args.target_accept, progressbar=args.progress)
    from feeler.calib.psychometric.outputs.checks import SLIP_PREFIX

    first = result.verdict.problems[0] if result.verdict.problems else ""
    if first.startswith(SLIP_PREFIX):          # stderr, before the table: the verdict's line comes after it
        import sys
        head = first.split(":")[0]
        print(f"note: {head}: the rows that fail the comparison design fit {head.split()[-1]}AFC proportions "
              f"correct far better (the verdict's first line says more)", file=sys.stderr, flush=True)
    print(f"M4 psychometric functions: {what}")
    print_summary(result)
    table = threshold_table(result)
    pc = float(table["pc"].iloc[0])
    shown, notes = display_table(table, _SHOW)
    location = ("DT = PSE → 75 % point" if not task.is_nafc else
                "pse = the location m, where Φ = ½; no DT in nAFC: see the threshold")
    exact = " by quadrature on the exact grid, where the summary above is of its draws" \
        if args.backend == "exact" else ""
    print(f"thresholds (µm; posterior mean and 95 % interval{exact}; {location}; threshold and slope "
          f"at P = {pc:g}; 'all' = {table['estimand'].iloc[-1]}):")
    with pd.option_context("display.width", 200, "display.max_columns", 30):
        print(shown.to_string(index=False))
    for line in notes:
        print(f"note: {line}")
    _report_warnings(caught)
    if args.out:
        out = save_psychometric(result, trials, args.out, force=True, note=note, plots=not args.no_plots)
        print(f"wrote {out / 'thresholds.csv'}, posterior.nc, summary.csv, verdict.json"
              f"{'' if args.no_plots else ', curves/*.png and curves/index.csv'}")
    return 0 if result.verdict.ok else 1


def run_finger_route(args) -> int:
    import numpy as np

    from feeler.calib.progress import stage
    from feeler.calib.psychometric.finger_route import RouteGrid, fit_finger_route, predict_p_higher, tau_report
    from feeler.errors import ArgumentError
    from feeler.psydata import read_trials, synthetic_note
    from feeler.rundir import prepare_out_dir, write_json

    from feeler.calib.psychometric.independent import check_draw_counts

    if args.n_tau < 2:
        raise ArgumentError("--n-tau", args.n_tau, "needs at least 2 grid nodes")   # at most MAX_N_TAU: feeler.cli
    check_draw_counts(args.chains, args.draws, flag="--")
    trials = read_trials(args.data, matrix_use="one condition at one speed pair, and the finger route needs trials at "
                                               "more than one; write the trial table's columns (README)")
    if "n_correct" in trials.columns:
        raise ArgumentError("DATA.csv", args.data, "the finger route needs comparison data "
                                                   "(n_comparison_higher), not nAFC (n_correct)")
    trials, dropped = _without_empty_rows(trials)
    note = synthetic_note(trials)
    _banner(note)
    if dropped:
        print(f"note: {dropped}")
    if args.out:
        prepare_out_dir(args.out, ("posterior.nc", "summary.csv", "verdict.json", "tau_report.json"),
                        force=args.force)
    stage(f"fitting tau, sigma_d and the lapse through skin {args.level} -> neuron -> observer "
          f"({args.n_tau} tau nodes)", args.progress)
    result = fit_finger_route(trials, rng=np.random.default_rng(args.seed), grid=RouteGrid(n_tau=args.n_tau),
                              level=args.level, chains=args.chains, draws=args.draws)
    print_summary(result)
    report = tau_report(result) | {"synthetic_data": bool(note), "data_note": note}
    if not result.verdict.ok:     # a failed fit agrees or disagrees with nothing (heights in mm 'agreed', P = 0.99)
        report["paper"] = "not compared: the verdict failed (its problems above)"
    if args.check_level:
        mean = result.summary.set_index("name")["mean"]
        kw = dict(tau_s=float(mean["tau_s"]), sigma_d_um=float(mean["sigma_d_um"]),
                  lapse=float(mean["lapse"]))
        stage(f"checking the fit with skin {args.check_level}", args.progress)
        p_fit = predict_p_higher(trials, level=args.level, **kw)
        p_chk = predict_p_higher(trials, level=args.check_level, **kw)
        report["check"] = {"level": args.check_level, "max_abs_dp": float(np.max(np.abs(p_fit - p_chk)))}
    lo, hi = report["tau_eti95_s"]
    print(f"tau: posterior mean {1e3 * report['tau_mean_s']:.1f} ms, 95 % interval "
          f"[{1e3 * lo:.1f}, {1e3 * hi:.1f}] ms (of the exact grid marginal; the summary above is of its draws)")
    print(f"paper: {report['paper']}")                   # gives P(tau <= 300 ms | data)
    if "check" in report:
        print(f"check at the posterior mean with {args.check_level}: max |ΔP| = "
              f"{report['check']['max_abs_dp']:.4f}")
    if args.out:
        out = result.save(args.out, force=True)
        write_json(out / "tau_report.json", report)
        print(f"wrote {out / 'tau_report.json'}, posterior.nc, summary.csv, verdict.json")
    return 0 if result.verdict.ok else 1
