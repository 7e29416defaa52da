"""Figures of the psychophysics fits.

- M4: the pooled PSE and DT per condition and the lapse, then every subject's PSE and DT
  per condition against the pooled interval;
- the finger route's (:mod:`feeler.calib.psychometric.finger_route`) posterior: the grid's
  own τ marginal (log axis, 300 ms marked), σ_d and the lapse (the grid's density when
  its draws sit on the grid's nodes; κ is a function of τ and is not drawn), and the
  paper's Fig. 6 at the fitted τ: accepted against presented height with the human PSEs.
"""
from __future__ import annotations

import json

import numpy as np

from feeler.reports.fit_plots import _UNITS, DENSITY, _density, _finite, _json, _summary_cols, conditions_of
from feeler.reports.model import error_span, log_axis, make_figure, subplots

__all__ = ["m4_figures", "route_marginals", "finger_route_fig6", "synthetic_inv", "SYNTHETIC_TITLE",
           "SYNTHETIC_CAPTION"]

#: title tail and caption head of a figure drawn from synthetic human data (the banner promises it)
SYNTHETIC_TITLE, SYNTHETIC_CAPTION = " (SYNTHETIC human data)", "SYNTHETIC human data, not measurements. "


def synthetic_inv(inv) -> bool:
    """Whether the run's human data are feeler's own synthetic ones."""
    from feeler.reports.humandata import human_data

    return bool(human_data(inv).label)


def m4_figures(result, draws, attrs, src, synthetic: bool = False) -> list:
    """M4: the pooled PSE and DT per condition and the lapse, then every subject's PSE and DT
    per condition against the pooled interval (indices mapped to subjects and conditions)."""
    conds = conditions_of(attrs)
    fig, axes = subplots(3, width_in=7.0 / 3, height_in=1.9)
    for ax, var, xl in zip(axes, ("pse_all", "dt_all"), ("PSE (µm)", "DT (µm)")):
        for c, cond in enumerate(conds):
            name = f"{var}[{c}]"
            if name in draws:
                _density(ax, draws[name], 40, label=cond, color=f"C{c}")
        ax.set(xlabel=xl, yticks=[])
        ax.legend(fontsize=5)
    if "lapse_all" in draws:
        _density(axes[2], draws["lapse_all"], 40, color="C2")
    axes[2].set(xlabel="lapse rate (pooled)", yticks=[])
    for ax in axes:
        ax.tick_params(labelsize=6)
        ax.set_ylabel(DENSITY, fontsize=6)
    title, head = (SYNTHETIC_TITLE, SYNTHETIC_CAPTION) if synthetic else ("", "")
    out = [make_figure("Pooled PSE and difference threshold per condition" + title, fig, src,
                       head + "All subjects pooled (the section's estimands); draws pooled over chains.")]
    subjects = _json(attrs.get("subjects"), [])
    fig, axes = subplots(2, width_in=3.5, height_in=min(0.2 * max(len(subjects) * len(conds), 4) + 0.9, 3.6))
    for ax, var, xl in zip(axes, ("pse", "dt"), ("PSE (µm)", "difference threshold (µm)")):
        names = [f"{var}[{s},{c}]" for s in range(len(subjects)) for c in range(len(conds))]
        names = [n for n in names if n in result.summary["name"].values]
        if not names:
            ax.set_visible(False)
            continue
        for c in range(len(conds)):
            sel = [n for n in names if n.endswith(f",{c}]")]
            mean, lo, hi = _summary_cols(result, sel)
            y = np.arange(len(sel))[::-1] * len(conds) + (len(conds) - 1 - c)
            ax.errorbar(mean, y, xerr=error_span(mean, lo, hi), fmt="o", ms=3, capsize=2, color=f"C{c}",
                        label=conds[c])
            pooled = f"{var}_all[{c}]"
            if pooled in result.summary["name"].values:
                _, plo, phi = _summary_cols(result, [pooled])
                ax.axvspan(plo[0], phi[0], color=f"C{c}", alpha=0.12)
        ticks = np.arange(len(subjects))[::-1] * len(conds) + (len(conds) - 1) / 2
        ax.set_yticks(ticks, subjects, fontsize=6)
        ax.set(xlabel=xl)
        ax.tick_params(axis="x", labelsize=6)
        ax.legend(fontsize=5)
    out.append(make_figure("Every subject's PSE and difference threshold" + title, fig, src,
                           head + "Mean and 95 % interval per subject and condition; shaded: the pooled 95 % "
                           "interval."))
    return out


def route_marginals(draws, attrs, src, synthetic: bool = False) -> list:
    """The finger route's posterior figure: τ (the grid's marginal), σ_d and the lapse."""
    fig, axes = subplots(3, width_in=7.0 / 3, height_in=1.9)
    grid, dens = _json(attrs.get("tau_grid_s"), []), _json(attrs.get("tau_marginal"), [])
    if grid and len(grid) == len(dens):
        g, d = np.asarray(grid, float) * 1e3, np.asarray(dens, float)
        axes[0].plot(g, d / d.max(), color="C0", label="grid marginal")
    elif "tau_s" in draws:
        _density(axes[0], _finite(draws["tau_s"]) * 1e3, 40, color="C0", label="draws")
    axes[0].axvline(300.0, color="C3", ls="--", lw=0.8, label="300 ms (paper)")
    axes[0].set(xlabel="τ (ms)", yticks=[])
    axes[0].set_ylabel(DENSITY + " / its peak", fontsize=6)
    log_axis(axes[0], "x")
    axes[0].legend(fontsize=5)
    on_nodes = "lapse" in draws and _lapse_on_grid(axes[2], draws["lapse"], _route_grid(attrs))
    for ax, name in zip(axes[1:], ("sigma_d_um", "lapse")):
        if name in draws and not (name == "lapse" and on_nodes):
            _density(ax, draws[name], 40, color="C1")
        ax.set(xlabel=_UNITS[name], yticks=[])
        ax.set_ylabel(DENSITY, fontsize=6)
    for ax in axes:
        ax.tick_params(labelsize=6)
    title, head = (SYNTHETIC_TITLE, SYNTHETIC_CAPTION) if synthetic else ("", "")
    lapse = (f"lapse: the grid's {on_nodes} nodes (triangles), each one's share of the draws spread over the prior "
             "cell it stands for, in proportion to the prior (dotted)" if on_nodes else "lapse: draws pooled")
    return [make_figure("Posterior of τ, σ_d and the lapse" + title, fig, src,
                        head + "τ: the grid's marginal density (normalised to its peak); σ_d: draws pooled; "
                        f"{lapse}. κ is a function of τ and is not drawn.")]


def _route_grid(attrs):
    """The finger route's grid from the posterior's ``grid`` attribute (None without one)."""
    from feeler.calib.psychometric.finger_route import RouteGrid

    try:
        fields = json.loads(attrs.get("grid", ""))
        return RouteGrid(**{k: tuple(v) if isinstance(v, list) else v for k, v in fields.items()})
    except (TypeError, ValueError, AttributeError):      # absent, not JSON, not a RouteGrid's fields
        return None


def _lapse_on_grid(ax, x, grid) -> int:
    """Draw the lapse's grid posterior as a density (:func:`lapse_density`) when every draw
    sits on one of ``grid``'s nodes; returns the number of nodes, 0 (nothing drawn) otherwise.
    A histogram of such draws is a comb of one spike per node (an outside reader asked why)."""
    from scipy.stats import beta

    from feeler.calib.psychometric.finger_route import lapse_density
    from feeler.models.psychometric import LAPSE_MAX

    x = _finite(x)
    if grid is None or not x.size or not np.isclose(x[:, None], grid.lapses()[None], rtol=1e-9, atol=0.0).any(1).all():
        return 0
    edges = grid.lapse_edges()
    top = float(LAPSE_MAX * beta.ppf(0.995, grid.lapse_a, grid.lapse_b))      # the prior's 99.5 % point
    lam = np.unique(np.concatenate([np.linspace(0.0, top, 400), edges[edges <= top]]))
    lam = np.sort(np.concatenate([lam, np.nextafter(edges[1:-1][edges[1:-1] <= top], 0.0)]))  # a step at each edge
    ax.plot(lam, lapse_density(grid, x, lam), color="C1", lw=0.9, label="posterior")
    ax.plot(lam, beta.pdf(lam / LAPSE_MAX, grid.lapse_a, grid.lapse_b) / LAPSE_MAX, ":", color="0.4", lw=0.8,
            label="prior")
    ax.plot(grid.lapses(), np.zeros(grid.n_lapse), "^", color="C1", ms=3.5, clip_on=False)   # not axis ticks
    ax.legend(fontsize=5)
    ax.set_xlim(0.0, top)
    ax.set_ylim(bottom=0.0)
    return grid.n_lapse


def finger_route_fig6(inv, tau_s: float, level: str, tau_rel: str):
    """Accepted against presented height at the fitted τ, with the human PSEs (or None
    without human thresholds)."""
    from feeler.calib.psychometric.finger_route import accepted_heights
    from feeler.reports.humandata import human_data

    human = human_data(inv)
    if human.pooled is None:
        return None
    speeds = sorted(set(human.pooled["standard_speed_mm_s"].astype(float)))
    heights = np.linspace(5.0, 15.0, 5)
    s_hat, _ = accepted_heights([(float(h), float(v)) for v in speeds for h in heights], np.array([tau_s]),
                                level=level)
    fig, ax = subplots(width_in=4.2, height_in=3.0)
    tag = " (SYNTHETIC)" if human.label else ""
    for k, v in enumerate(speeds):
        ax.plot(heights, s_hat[0, k * len(heights):(k + 1) * len(heights)], "-", color=f"C{k}",
                label=f"finger route, {v:g} mm/s")
        for _, r in human.pooled[human.pooled["standard_speed_mm_s"].astype(float) == v].iterrows():
            std = human.standard_um(r)
            pse, lo, hi = (human.value(r, c).value for c in ("pse_um", "pse_lb_um", "pse_ub_um"))
            if np.isfinite(std) and np.isfinite(pse):
                ax.errorbar([std], [pse], yerr=[[pse - lo], [hi - pse]], fmt="s", ms=4, color=f"C{k}", capsize=3,
                            label=f"human PSE{tag}, {v:g} mm/s")
    ax.plot(heights, heights, "k:", lw=0.7, label="accepted = presented")
    ax.set(xlabel="presented step height (µm)", ylabel="accepted step height (µm)",
           title=f"At the fitted τ = {tau_s * 1e3:.0f} ms (skin {level.upper()})")
    ax.legend(fontsize=6)
    return make_figure("Accepted against presented step height at the fitted τ" + (SYNTHETIC_TITLE if tag else ""),
                       fig, (tau_rel, human.thresholds_rel) + ((human.trials_rel,) if human.trials_rel else ()),
                       (SYNTHETIC_CAPTION if tag else "") + "Line: κ(τ)·peak z of the finger chain at the posterior "
                       "median τ; squares: pooled human "
                       "PSEs of the standard (95 % intervals).")
