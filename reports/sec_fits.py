"""A section per fitted model: verdict, every parameter's posterior by name, the
diagnostics table and the priors. A failed verdict marks the section ``failed`` so the
report puts it first under a red banner.

What is drawn depends on the model (:mod:`feeler.reports.fit_plots`) and the backend:
chains are compared (marginals per chain, traces) only for samplers (NUTS, emcee), whose
chains can disagree; exact, Laplace and grid posteriors are independent draws, shown
pooled, and a grid's own marginal is drawn as the curve it is.
"""
from __future__ import annotations

import dataclasses
import json
import re

from feeler.reports.model import Note, Section, Table, fmt, interval
from feeler.reports.readers import load_fit

__all__ = ["fit_section", "fit_inputs", "SAMPLERS", "summary_table", "readable_prior", "independent_draws"]

SAMPLERS = ("nuts", "emcee", "pymc", "mcmc")
#: fits of the human 2AFC trials: labelled SYNTHETIC when the trials are
HUMAN_MODELS = ("m4", "finger-route")


def _is_sampler(backend: str) -> bool:
    return any(s in backend.lower() for s in SAMPLERS)


def _fixed(r) -> bool:
    """An entry with the same value at every draw (sd 0, its interval one point): the
    verdict skips it (calib.diagnostics), and R-hat and ESS mean nothing for it."""
    lo, hi = r.get("eti95_lb", r["mean"]), r.get("eti95_ub", r["mean"])
    return r.get("sd") == 0 and lo == hi == r["mean"]


#: the verdict's rule per kind of fit (calib.diagnostics.diagnose; calib.psychometric.independent)
RULE_JUDGED = ("A fit passes with R-hat ≤ 1.01 and bulk ESS ≥ 400 for every entry (fixed ones excepted) and no "
               "divergences.")
RULE_JUDGED_DRAWS = ("A fit passes with R-hat ≤ 1.01 and bulk ESS ≥ 400 for every entry (fixed ones excepted), "
                     "estimated here from independent draws, and no divergences.")
RULE_INDEPENDENT = ("Independent draws: the verdict does not judge the R-hat and ESS shown (R-hat is noise for them, "
                    "their ESS is their number); it needs at least 400 draws in all and passes the model's own "
                    "checks.")


def independent_draws(model: str, backend: str) -> bool:
    """True for fits judged by their number of draws: M4 and the finger route without NUTS
    (calib.psychometric's independent_result); M1 and M2 are judged by R-hat and ESS."""
    return model in ("m4", "finger-route") and "nuts" not in backend.lower()


def summary_table(result, labels: dict, src: str, model: str = "") -> Table:
    """Mean, sd, 95 % interval, R-hat and ESS of every parameter entry, named by ``labels``;
    a fixed entry shows "fixed" and no R-hat or ESS; the caption states the verdict's rule
    for this fit's model and backend."""
    s = result.summary
    has = set(s.columns)
    rows = []
    for _, r in s.iterrows():
        if _fixed(r):
            rows.append((labels.get(r["name"], r["name"]), f"{fmt(r['mean'], 4)} (fixed)", "0", "—", "—", "—"))
            continue
        ci = interval(r["mean"], r.get("eti95_lb"), r.get("eti95_ub"), 4) if {"eti95_lb", "eti95_ub"} <= has \
            else fmt(r["mean"])
        rows.append((labels.get(r["name"], r["name"]), ci, fmt(r.get("sd"), 3), fmt(r.get("r_hat"), 4),
                     fmt(r.get("ess_bulk"), 4), fmt(r.get("ess_tail"), 4)))
    rule = (RULE_INDEPENDENT if independent_draws(model, result.backend) else
            RULE_JUDGED if _is_sampler(result.backend) else RULE_JUDGED_DRAWS)
    return Table("Posterior summary and diagnostics", ("parameter", "mean [95 % interval]", "sd", "R-hat",
                                                       "ESS bulk", "ESS tail"), tuple(rows), (src,),
                 caption="Equal-tailed intervals. " + rule
                 + (" fixed: the same value at every draw (no R-hat or ESS)." if any(r[1].endswith("(fixed)")
                                                                                  for r in rows) else ""))


_MATRIX = re.compile(r"\[\s*\[[-+0-9.eE,\s\[\]]*\]\s*\]")


def _matrix_text(match) -> str:
    """A NumPy repr "[[4., 0.], [0., 5.]]" as rows "(4 0; 0 5)"."""
    rows = re.findall(r"\[([^\[\]]*)\]", match.group(0))
    cells = [[fmt(float(x), 4) for x in re.split(r"[,\s]+", r.strip()) if x] for r in rows]
    return "(" + "; ".join(" ".join(c) for c in cells) + ")"


def readable_prior(text: str) -> str:
    """A prior as written by the fit, with matrices as rows "(4 0 0; 0 5 0; 0 0 4)" and
    "um" as "µm"."""
    text = _MATRIX.sub(_matrix_text, text)
    return re.sub(r"(?<=\d) um\b", " µm", text)


def _ppc_note(attrs, src) -> list:
    if "ppc_coverage90" not in attrs:
        return []
    edge = json.loads(attrs.get("checks", "{}")).get("window_edge", [])          # M2's window at an end of its range
    return [Note(f"Window: {line}.", sources=(src,)) for line in edge] + [
        Note(f"Posterior predictive check: the 90 % predictive intervals hold "
             f"{100 * float(attrs['ppc_coverage90']):.1f} % of the scans' labelled steps; predictive "
             f"p-value {fmt(attrs.get('ppc_p_value'), 3)}.", sources=(src,))]


def _n_draws(result) -> int:
    sizes = result.posterior["posterior"].sizes
    return int(sizes.get("chain", 1) * sizes.get("draw", 0))


def _decoder_names_note(model: str, attrs, src) -> list:
    """M2: its a, h and τ are the decoder's, not the paper's neuron parameters (an outside
    reader compared the window τ with the scene's τ, which lay outside its interval)."""
    if model != "m2":
        return []
    true_tau = ""
    scene = attrs.get("scene_toml")
    if scene:
        match = re.search(r"^tau_s\s*=\s*([0-9.eE+-]+)", str(scene), flags=re.M)
        if match:
            true_tau = f" (the scene's neuron: τ = {fmt(float(match.group(1)), 4)} s)"
    return [Note("a and h are the line from the peak window sum P (a strain) to the step, z = a·P − h (mm; a in mm "
                 "per unit strain), not the paper's gain "
                 "(V s) and threshold (V); τ is the window that best tells the plates apart (each window weighted by "
                 f"how well it predicts the left-out labels), not an estimate of the neuron's time constant{true_tau}.",
                 sources=(src,))]


def _reading_note(attrs, src) -> list:
    """M2: how the training scans read when each is left out, overall and per mode."""
    if "loo_reading" not in attrs:
        return []
    from feeler.calib.neuron.fit import reading_text

    by_mode = json.loads(attrs.get("mode_decoders", "{}"))
    modes = "; ".join(f"{k}s {100 * v['loo']['accuracy']:.0f} % (the most common plate alone "
                      f"{100 * v['loo']['base_accuracy']:.0f} %)" for k, v in by_mode.items() if "loo" in v)
    return [Note(f"Leave-one-out reading: {reading_text(json.loads(attrs['loo_reading']))}"
                 + (f". Each scan is read by its mode's decoder, as classify reads it: {modes}" if modes else "") + ".",
                 sources=(src,))]


def fit_inputs(inv, spec) -> None:
    """Read what the fit's section shows beside the fit (read already, :func:`feeler.reports.
    build.read_inputs`) before the report's first figure: the human data of a human fit,
    the campaign's true C beside M1, the τ report, thresholds.csv and the curves it lists."""
    from feeler.reports.fit_plots import plot_inputs

    part = spec.parts[0]
    if part.model in HUMAN_MODELS:
        from feeler.reports.humandata import human_data

        human_data(inv)
    plot_inputs(inv, part)
    if part.model == "finger-route" and inv.has(part.path("tau_report.json")):
        _tau_report(inv, part)
    if inv.has(part.path("thresholds.csv")):
        from feeler.reports.m4_extras import curve_items, thresholds_frame

        thresholds_frame(inv, part)
        curve_items(inv, part)


def fit_section(inv, spec) -> Section:
    """Verdict, posterior plots chosen for the model, the diagnostics and the priors."""
    from feeler.reports.fit_plots import labels_of, plate_steps, plots_of

    part = spec.parts[0]
    result = load_fit(inv.run_dir / part.rel, inv)
    post_rel, verdict_rel = part.path("posterior.nc"), part.path("verdict.json")
    verdict = result.verdict
    if verdict.ok:
        blocks = [Note(f"Verdict: passed every diagnostic (backend {result.backend}, {fmt(result.seconds, 3)} s).",
                       sources=(verdict_rel,))]
    else:
        blocks = [Note("Verdict: FAILED — do not use this posterior. " + "; ".join(verdict.problems),
                       level="failed", sources=(verdict_rel,))]
    attrs = dict(result.posterior["posterior"].attrs)
    if part.model in HUMAN_MODELS:
        from feeler.reports.humandata import human_data

        human = human_data(inv)
        if human.label:
            blocks.append(Note(f"Fitted to {human.label}", level="synthetic",
                               sources=(human.trials_rel or human.thresholds_rel,)))
    blocks += plots_of(inv, part, result, attrs, sampler=_is_sampler(result.backend))
    blocks += _ppc_note(attrs, post_rel) + _reading_note(attrs, post_rel) + _decoder_names_note(part.model, attrs, post_rel)
    table = summary_table(result, labels_of(part.model, attrs, result.summary["name"], plate_steps(result)),
                          part.path("summary.csv"), part.model)
    if inv.has(part.path("thresholds.csv")):        # the same quantities integrated on the grid (M4)
        table = dataclasses.replace(table, caption=table.caption + (
            f" From the {_n_draws(result)} draws: the thresholds table below integrates the posterior itself, so the "
            "ends of an interval can differ from these by the draws' Monte Carlo error (a few % in a long tail)."))
    blocks.append(table)
    if result.priors:
        rows = tuple((readable_prior(str(k)), readable_prior(str(v))) for k, v in result.priors.items())
        blocks.append(Table("Priors", ("parameter", "prior"), rows, (post_rel,)))
    if part.model == "finger-route" and inv.has(part.path("tau_report.json")):
        blocks += _tau_blocks(inv, part)
    if inv.has(part.path("thresholds.csv")):
        from feeler.reports.m4_extras import curves_gallery, thresholds_table

        blocks.append(thresholds_table(inv, part))
        gallery = curves_gallery(inv, part)
        if gallery is not None:
            blocks.append(gallery)
    return Section(spec.key, spec.title, tuple(blocks), failed=not verdict.ok, problems=tuple(verdict.problems))


def _tau_report(inv, part) -> tuple[dict, float]:
    """(tau_report.json, its τ median in s; fields checked: :func:`~feeler.reports.claims_human.read_tau_report`)."""
    from feeler.reports.claims_human import read_tau_report

    rep = read_tau_report(inv, part.path("tau_report.json"))
    return rep, float(rep["tau_median_s"])


def _tau_blocks(inv, part) -> list:
    """The finger route's τ report in words and Fig. 6 at the fitted τ with the human points."""
    from feeler.reports.psy_plots import finger_route_fig6

    rel = part.path("tau_report.json")
    rep, tau_s = _tau_report(inv, part)
    eti = [float(x) * 1e3 for x in rep.get("tau_eti95_s", [])][:2] or [float("nan")] * 2
    paper = str(rep.get("paper", ""))               # the paper's claim against P(τ ≤ 300 ms | data), P included
    tail = (f"The paper: {paper}." if paper else
            f"P(τ ≤ 300 ms | data) = {fmt(rep.get('p_tau_le_300ms'), 3)}.")
    blocks = [Note(f"τ posterior median {fmt(tau_s * 1e3, 3)} ms, 95 % interval {fmt(eti[0], 3)}–{fmt(eti[1], 3)} ms. "
                   + tail, sources=(rel,))]
    fig = finger_route_fig6(inv, tau_s, str(rep.get("skin_level") or "l0"), rel)
    if fig is not None:
        blocks.append(fig)              # after its summary: a lone line of text made a page (review s49)
    return blocks
