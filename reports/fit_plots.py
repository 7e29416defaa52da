"""Posterior figures of each model, every parameter named by what it is.

- M1: the matrix C entry by entry against the true C when the run holds the simulated
  sensor's truth, marginals of all nine entries, of σ per axis and of cond(C);
- M2: a, τ, h and σ with their units;
- M4: the pooled PSE and DT per condition and the lapse, then every subject's PSE and DT
  per condition against the pooled interval (indices mapped to subjects and conditions);
- finger route: the grid's own τ marginal (log axis, 300 ms marked), σ_d and the lapse
  (κ is a function of τ and is not drawn);
- any other model: the marginals of all its entries, six to a figure.

Samplers (NUTS, emcee) also get one line per chain and traces; other backends' draws are
independent and pooled.
"""
from __future__ import annotations

import json

import numpy as np

from feeler.reports.model import Figure, Note, log_axis, make_figure, subplots

__all__ = ["labels_of", "plots_of", "finger_route_fig6", "conditions_of", "split_finite", "NO_FINITE", "DENSITY",
           "fixed_and_copies", "even_chunk"]

_UNITS = {"a": "a (mm per unit strain)", "tau_s": "τ (s)", "h": "h (mm)", "sigma_mm": "σ (mm)",
          "sigma_d_um": "σ_d (µm)", "lapse": "lapse", "cond_C": "cond(C)", "lapse_all": "lapse (pooled)"}
_PER_FIG = 6
#: the y label of a marginal panel (its ticks are left out: the scale is per unit of x)
DENSITY = "density"
#: what stands in for the figure of an entry whose draws are all NaN or infinite
NO_FINITE = "no finite draws: the fit failed, see its verdict"


def split_finite(draws: dict) -> tuple[dict, list[str]]:
    """(the entries of ``draws`` with at least one finite draw, the names of those with
    none): a failed fit may leave some parameters undefined, and their histograms cannot
    be drawn."""
    kept, empty = {}, []
    for name, x in draws.items():
        if np.isfinite(np.asarray(x, float)).any():
            kept[name] = x
        else:
            empty.append(name)
    return kept, empty


def fixed_and_copies(draws: dict, names) -> tuple[dict, dict]:
    """({name: value} of entries equal at every draw, {name: earlier name} of entries equal
    draw for draw to an earlier one, to rounding): neither gets a panel of its own."""
    fixed, copies, seen = {}, {}, []
    for name in names:
        x = np.asarray(draws[name], float)
        if x.size and np.all(x == x.flat[0]):
            fixed[name] = float(x.flat[0])
            continue
        twin = next((n for n in seen if np.shape(draws[n]) == x.shape
                     and np.allclose(draws[n], x, rtol=1e-12, atol=0.0)), None)
        if twin is None:
            seen.append(name)
        else:
            copies[name] = twin
    return fixed, copies


def even_chunk(n: int, most: int) -> int:
    """Panels per figure: as few figures as ``most`` a figure allows, filled evenly (19
    entries: 5, 5, 5, 4, not 6, 6, 6, 1 with a lone full-width panel)."""
    figures = max(1, -(-n // most))
    return max(1, -(-n // figures))


def _finite(x) -> np.ndarray:
    """The finite values of ``x``, flattened."""
    x = np.ravel(np.asarray(x, float))
    return x[np.isfinite(x)]


def _density(ax, x, bins: int, **kw) -> None:
    """A step histogram of the finite draws ``x``; draws that are one value (to rounding: a
    parameter the model pins, such as a two-plate decoder's plate means) are a vertical line,
    where a histogram has no width to divide into bins (numpy raised 'Too many bins'), or
    whose bins would be rounding error (ticks 1e-17 apart)."""
    x = _finite(x)
    if not x.size:
        return
    if np.ptp(x) <= max(1e-9 * float(np.max(np.abs(x))), 1e-12):     # 1e-12: a zero that rounding spreads
        kw = {k: v for k, v in kw.items() if k in ("color", "label", "lw")}
        v = float(np.median(x))
        v = v if abs(v) > 1e-12 else 0.0           # a zero that rounding left at 1e-17
        ax.axvline(v, **kw)
        half = 0.05 * abs(v) if v else 1.0         # else the axis spans the rounding: ticks 1e-14 apart
        ax.set_xlim(v - half, v + half)
        return
    ax.hist(x, bins=bins, histtype="step", density=True, **kw)


def _json(value, default):
    if isinstance(value, str):
        try:
            return json.loads(value)
        except json.JSONDecodeError:
            return default
    return default if value is None else list(value)


def conditions_of(attrs) -> list[str]:
    """M4 conditions as words, "10 µm at 40 vs 20 mm/s", in index order."""
    out = []
    for c in _json(attrs.get("conditions"), []):
        c = list(c) + [np.nan] * 3
        out.append(f"{c[0]:g} µm at {c[1]:g} vs {c[2]:g} mm/s")
    return out


def _m1_label(name: str) -> str:
    base, _, idx = name.partition("[")
    ij = [int(i) for i in idx.rstrip("]").split(",") if i.strip().isdigit()]
    if base == "C" and len(ij) == 2:
        return f"C[{ij[0]},{ij[1]}]  U_{'xyz'[ij[0]]} ← F_{'xyz'[ij[1]]} (mm/N)"
    if base == "K" and len(ij) == 2:
        return f"K[{ij[0]},{ij[1]}]  F_{'xyz'[ij[0]]} ← U_{'xyz'[ij[1]]} (N/mm)"
    if base == "sigma_n" and len(ij) == 1:
        return f"σ_{'xyz'[ij[0]]} (N)"
    return _UNITS.get(name, name)


def labels_of(model: str, attrs, names) -> dict:
    """Readable names of summary entries (M1 entries by axis, M4 indices as subjects and
    conditions, units where the model states them)."""
    if model == "m1":
        return {n: _m1_label(n) for n in names}
    if model != "m4":
        return {n: _UNITS.get(n, n) for n in names}
    subjects, conds = _json(attrs.get("subjects"), []), conditions_of(attrs)
    out = {}
    for n in names:
        base, _, idx = n.partition("[")
        parts = [int(i) for i in idx.rstrip("]").split(",") if i.strip().isdigit()] if idx else []
        if base.endswith("_all"):
            who, rest = "all", parts
        else:
            who, rest = (subjects[parts[0]] if parts and parts[0] < len(subjects) else "?"), parts[1:]
        cond = conds[rest[0]] if rest and rest[0] < len(conds) else ""
        out[n] = f"{base.removesuffix('_all')} · {who}" + (f" · {cond}" if cond else "")
    return out


def _marginals(draws, names, labels, *, per_chain: bool, title: str, src) -> Figure:
    from matplotlib.ticker import MaxNLocator

    n = len(names)
    ncols = 4 if n == 4 else min(n, 3)
    fig, axes = subplots(ncols, nrows=-(-n // ncols), width_in=7.0 / ncols, height_in=1.45, squeeze=False)
    for ax in axes.ravel()[n:]:
        ax.set_visible(False)
    for ax, name in zip(axes.ravel(), names):
        x = np.asarray(draws[name], float).reshape(-1, np.shape(draws[name])[-1])
        for chain in (x if per_chain else x.reshape(1, -1)):
            _density(ax, chain, 30, lw=0.9)                 # a chain of a failed fit may hold NaN
        lo, hi = np.quantile(_finite(x), [0.025, 0.975])
        ax.axvspan(lo, hi, color="0.85", zorder=0)
        ax.set_title(labels.get(name, name), fontsize=7)
        ax.xaxis.set_major_locator(MaxNLocator(3))
        ax.ticklabel_format(axis="x", style="plain", useOffset=False)
        ax.tick_params(labelsize=6)
        ax.set_yticks([])
        ax.set_ylabel(DENSITY, fontsize=6)
    how = "one line per chain (chains that agree overlap)" if per_chain else "all draws pooled"
    return make_figure(title, fig, src, f"Marginal posterior densities, {how}; grey: 95 % interval.")


def _traces(draws, names, labels, src) -> Figure:
    n = len(names)
    fig, axes = subplots(min(n, 3), nrows=-(-n // 3), width_in=7.0 / min(n, 3), height_in=1.3, squeeze=False)
    for ax in axes.ravel()[n:]:
        ax.set_visible(False)
    for ax, name in zip(axes.ravel(), names):
        x = np.asarray(draws[name], float).reshape(-1, np.shape(draws[name])[-1])
        step = max(1, x.shape[1] // 300)
        for chain in x:
            ax.plot(np.arange(0, x.shape[1], step), chain[::step], lw=0.4, alpha=0.8)
        ax.set_title(labels.get(name, name), fontsize=7)
        ax.set_xlabel("draw", fontsize=6)
        ax.tick_params(labelsize=6)
    return make_figure("Traces", fig, src, "Each chain's draws in order (every "
                       f"{max(1, np.shape(draws[names[0]])[-1] // 300)}th shown).")


def _forest(ax, labels, mean, lo, hi, *, truth=None, band=None, color="C0") -> None:
    y = np.arange(len(labels))[::-1]
    ax.errorbar(mean, y, xerr=[np.subtract(mean, lo), np.subtract(hi, mean)], fmt="o", ms=3, capsize=2,
                color=color, label="posterior mean, 95 % interval")
    if truth is not None:
        ax.plot(truth, y, "x", color="k", ms=5, label="true value (simulated)")
    if band is not None:
        ax.axvspan(*band, color=color, alpha=0.15, label="pooled 95 % interval")
    ax.set_yticks(y, labels, fontsize=6)
    ax.tick_params(axis="x", labelsize=6)


def _summary_cols(result, names):
    s = result.summary.set_index("name").loc[names]
    return s["mean"].to_numpy(), s["eti95_lb"].to_numpy(), s["eti95_ub"].to_numpy()


def _true_c(inv):
    from feeler.reports.readers import read_json

    part = inv.first("calibration-data", prefer="sensor-calibration")
    if part is None or not inv.has(part.path("truth.json")):
        return None, None
    truth = read_json(inv.run_dir / part.path("truth.json"))
    c = truth.get("scene", {}).get("sensor", {}).get("c_mm_per_n")
    return (np.asarray(c, float).ravel(), part.path("truth.json")) if c is not None else (None, None)


def _m1(inv, result, draws, sampler, src) -> list:
    names = [f"C[{i},{j}]" for i in range(3) for j in range(3)]
    truth, truth_rel = _true_c(inv)
    fig, ax = subplots(width_in=4.6, height_in=2.6)
    _forest(ax, [f"C[{i},{j}]  U_{'xyz'[i]} ← F_{'xyz'[j]}" for i in range(3) for j in range(3)],
            *_summary_cols(result, names), truth=truth)
    ax.set(xlabel="compliance (mm/N)", title="Force→displacement matrix C, entry by entry")
    ax.legend(fontsize=6)
    out = [make_figure("The matrix C", fig, src + ((truth_rel,) if truth_rel else ()),
                       "Posterior mean and 95 % interval of every entry" +
                       ("; ×: the simulated sensor's true C." if truth is not None else "."))]
    labels = {n: n for n in names} | {f"sigma_n[{j}]": f"σ_{'xyz'[j]} (N)" for j in range(3)} | {"cond_C": "cond(C)"}
    out.append(_marginals(draws, names[:6], labels, per_chain=sampler, title="Marginals of C, rows x and y", src=src))
    rest = names[6:] + [n for n in ("sigma_n[0]", "sigma_n[1]", "sigma_n[2]", "cond_C") if n in draws]
    out.append(_marginals(draws, rest, labels, per_chain=sampler, title="Marginals of C row z, σ and cond(C)",
                          src=src))
    return out


#: title tail and caption head of a figure drawn from synthetic human data (the banner promises it)
SYNTHETIC_TITLE, SYNTHETIC_CAPTION = " (SYNTHETIC human data)", "SYNTHETIC human data, not measurements. "


def _synthetic_inv(inv) -> bool:
    from feeler.reports.humandata import human_data

    return bool(human_data(inv).label)


def _m4(result, draws, attrs, labels, src, synthetic: bool = False) -> list:
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
            ax.errorbar(mean, y, xerr=[mean - lo, hi - mean], fmt="o", ms=3, capsize=2, color=f"C{c}",
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


def _finger_route(draws, attrs, src, synthetic: bool = False) -> list:
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


def plots_of(inv, part, result, attrs, *, sampler: bool) -> list:
    """The figures of one fit (see the module docstring); entries without a finite draw
    are named in a note instead of drawn (:data:`NO_FINITE`)."""
    draws, empty = split_finite(result.draws())
    src = (part.path("posterior.nc"),)
    labels = labels_of(part.model, attrs, list(draws) + empty)
    if part.model == "m1" and all(f"C[{i},{j}]" in draws for i in range(3) for j in range(3)):
        out = _m1(inv, result, draws, sampler, src)
        key = ["C[0,0]", "C[1,1]", "C[2,2]", "sigma_n[0]", "sigma_n[1]", "sigma_n[2]"]
    elif part.model == "m4":
        out = _m4(result, draws, attrs, labels, src, _synthetic_inv(inv))
        key = [n for n in draws if n.startswith(("pse_all", "dt_all", "lapse_all"))][:_PER_FIG]
    elif part.model == "finger-route":
        out = _finger_route(draws, attrs, src, _synthetic_inv(inv))
        key = [n for n in ("tau_s", "sigma_d_um", "lapse") if n in draws]
    else:
        names = [n for n in result.summary["name"] if n in draws]
        fixed, copies = fixed_and_copies(draws, names)
        names = [n for n in names if n not in fixed and n not in copies]
        per = even_chunk(len(names), _PER_FIG)
        out = [_marginals(draws, names[i:i + per], labels, per_chain=sampler, src=src,
                          title="Marginal posteriors" + (f" ({i // per + 1})" if len(names) > per else ""))
               for i in range(0, len(names), per)]
        key = names[:_PER_FIG]
        if fixed or copies:
            words = [f"{labels.get(n, n)} = {v:g} at every draw (fixed)" for n, v in fixed.items()]
            words += [f"{labels.get(n, n)} equals {labels.get(t, t)} draw for draw" for n, t in copies.items()]
            out.append(Note("Not drawn: " + "; ".join(words) + ".", sources=src))
    if empty:
        out.insert(0, Note(f"{', '.join(labels.get(n, n) for n in empty)}: {NO_FINITE}.", level="failed",
                           sources=src))
    if sampler and key:
        out.append(_traces(draws, [k for k in key if k in draws], labels, src))
    elif not sampler:
        out.append(Note(f"Backend {result.backend}: independent draws, so chains are not compared and no "
                        "traces are drawn."))
    return out


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
